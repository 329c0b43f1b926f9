"""The default layout of a run's recording (``rr.send_blueprint``): the 3D view of robot and
scene beside the agent graph and a_ta's state; below, the traffic log and the per-channel
size and bandwidth time series (paper Figures 12 and 13), the joints and the wrist
force/torque."""

from __future__ import annotations

import rerun as rr
import rerun.blueprint as rrb

from services.viewer import robot, traffic


def blueprint() -> rrb.Blueprint:
    """The roco layout."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name="robot and scene", origin="/world"),
                rrb.Vertical(
                    rrb.GraphView(name="agents and channels", origin=f"/{traffic.GRAPH}"),
                    rrb.TextLogView(
                        name="a_ta: L_SW state and step",
                        origin="/task",
                        contents=["/task/**"],
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
