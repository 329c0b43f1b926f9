"""The experiment report of a run folder (paper §5.7, Tables 7 and 8).

``build_report(run_dir)`` returns the figures as data (:class:`Report`);
``write_report(run_dir)`` renders them to ``run_dir/report.md``.

Modules: ``load`` (tolerant reading of the run folder), ``stats`` (sizes, channels, Table 8
matrix), ``planning`` (planning phases), ``timeline`` (Table 7 events), ``content`` (spheres
in the bowl), ``notices`` (what agents told the person), ``paper`` (the paper's figures),
``markdown`` (rendering), ``build`` (assembly).
"""

from services.report.build import REPORT_MD, build_report, write_report
from services.report.model import (
    AgentMatrix,
    ChannelStats,
    ContentOutcome,
    Event,
    Header,
    PlanPhase,
    Report,
    SizeStats,
)

__all__ = [
    "REPORT_MD",
    "AgentMatrix",
    "ChannelStats",
    "ContentOutcome",
    "Event",
    "Header",
    "PlanPhase",
    "Report",
    "SizeStats",
    "build_report",
    "write_report",
]
