"""The paper's comparison tables and the report's figures, built from the metrics files."""

from rigmap.reports.build import ReportFiles, build_report
from rigmap.reports.metrics_tree import ReportInputError, load_metrics, read_result
from rigmap.reports.settings import ReportSettings

__all__ = [
    "ReportFiles",
    "ReportInputError",
    "ReportSettings",
    "build_report",
    "load_metrics",
    "read_result",
]
