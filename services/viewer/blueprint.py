"""The default layout of a run's recording (``rr.send_blueprint``): the 3D view of robot and
scene beside the head camera's image, the agent graph, a_ta's state and a_co's queue; below,
the traffic log and the time series: per-channel size and bandwidth (paper Figures 12 and
13), the joints, the wrist force/torque, the container content, the control loop's timing
and a_co's queue length."""

from __future__ import annotations

import rerun as rr
import rerun.blueprint as rrb

from services.viewer import camera, robot, tasks, traffic


def blueprint() -> rrb.Blueprint:
    """The roco layout."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name="robot and scene", origin="/world"),
                rrb.Vertical(
                    rrb.Spatial2DView(name="head camera", origin=f"/{camera.ENTITY}"),
                    rrb.Tabs(
                        rrb.GraphView(name="agents and channels", origin=f"/{traffic.GRAPH}"),
                        rrb.TextDocumentView(
                            name="a_co: command queue", origin=f"/{tasks.QUEUE}", contents="$origin"
                        ),
                        rrb.TextLogView(
                            name="a_ta: L_SW state and step",
                            origin="/task",
                            contents=["/task/**", f"- /{tasks.QUEUE}/**"],
                        ),
                    ),
                ),
                column_shares=[3, 2],
            ),
            rrb.Horizontal(
                rrb.TextLogView(name="traffic", origin=f"/{traffic.TRAFFIC_LOG}"),
                rrb.Tabs(
                    rrb.TimeSeriesView(name="size [B] per channel", origin=f"/{traffic.SIZE}"),
                    rrb.TimeSeriesView(name="bandwidth [kbit/s] per channel", origin=f"/{traffic.BANDWIDTH}"),
                    rrb.TimeSeriesView(name="joints [rad]", origin=f"/{robot.JOINTS}"),
                    rrb.TimeSeriesView(name="wrist F/T [N, N·m]", origin=f"/{robot.FT}"),
                    rrb.TimeSeriesView(name="container content", origin=f"/{robot.CONTENT}"),
                    rrb.TimeSeriesView(
                        name="loop compute and lateness [µs]",
                        origin=f"/{robot.TIMING}",
                        contents=[f"/{robot.TIMING}/compute/**", f"/{robot.TIMING}/lateness/**"],
                    ),
                    rrb.TimeSeriesView(name="loop overruns", origin=f"/{robot.TIMING}/overruns"),
                    rrb.TimeSeriesView(name="a_co queue length", origin=f"/{tasks.LENGTH}"),
                ),
                column_shares=[3, 2],
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=False,
    )


def send(stream: rr.RecordingStream) -> None:
    """Send the roco layout as the recording's default blueprint."""
    stream.send_blueprint(blueprint(), make_active=True, make_default=True)
