"""The names of the reported metrics, their units and the report's table rows (no torch: a re-run served
from the store prints and publishes its metrics without importing the evaluation)."""

from __future__ import annotations

from typing import Any

METRIC_KEYS = ("w_mpjpe", "wa_mpjpe", "mpjpe", "pa_mpjpe", "mpvpe", "accel", "ate", "ids", "pck", "jitter", "fs")
"""The headline metrics in the paper's order, with the field's meaning (docs/METRICS.md)."""

METRIC_UNITS = {
    "w_mpjpe": "mm", "wa_mpjpe": "mm", "mpjpe": "mm", "pa_mpjpe": "mm", "mpvpe": "mm", "accel": "m/s^2",
    "ate": "m", "ids": "switches/sequence", "pck": "%", "jitter": "10 m/s^3", "fs": "mm/frame",
    "w_mpjpe_track": "mm", "wa_mpjpe_track": "mm", "accel_world": "mm/frame^2", "fs_gt": "mm",
    "fs_truth": "mm/frame",
    "mpjpe_world": "mm", "mpvpe_world": "mm", "ate_mean": "m", "ids_total": "switches",
    "ids_per_cut": "switches/cut", "ids_within_shots": "switches", "pck_005": "%", "coverage": "fraction",
}
"""The unit of every number :func:`multithumbs.metrics.evaluate.summarize` reports (the headline keys first, in the paper's order)."""


def report_rows(report: dict[str, Any]) -> list[dict[str, Any]]:
    """A report as table rows ``{"metric", "value", "unit"}``: every number of :data:`METRIC_UNITS`, then
    how each sequence's ATE was aligned and the switches through each cut, as text."""
    rows = [{"metric": k, "value": report[k], "unit": unit} for k, unit in METRIC_UNITS.items() if k in report]
    for key in ("ate_alignment", "ids_at_cuts"):
        if key in report:
            rows.append({"metric": key, "value": "; ".join(str(v) for v in report[key]), "unit": ""})
    return rows
