"""The evaluation of the localizer and its baselines over many simulated runs.

``python -m tileviz evaluate`` (:mod:`tileviz.evaluation.cli`). The package is split by job:
:mod:`~tileviz.evaluation.scenarios` (conditions and fault schedules),
:mod:`~tileviz.evaluation.simulate` (one run: simulator, vision, every method),
:mod:`~tileviz.evaluation.metrics` (what is measured; the metric definitions),
:mod:`~tileviz.evaluation.report` (CSV, Markdown, plots) and
:mod:`~tileviz.evaluation.campaign` (many runs, a process pool).
"""

from tileviz.evaluation.campaign import evaluate
from tileviz.evaluation.cli import main
from tileviz.evaluation.events import EventOutcome, event_outcomes, fault_events, noticed
from tileviz.evaluation.metrics import (
    CALIBRATION_COLUMNS,
    COLUMNS,
    FAULT_COLUMNS,
    aggregate,
    calibration,
    metrics,
)
from tileviz.evaluation.report import (
    calibration_table,
    figures,
    markdown_table,
    write_csv,
    write_outputs,
)
from tileviz.evaluation.scenarios import (
    DEFAULT_SCENARIOS,
    RECOVERY_MAX_SLIP,
    SCENARIOS,
    FaultEvent,
    Scenario,
    fault_schedule,
)
from tileviz.evaluation.simulate import (
    FAULT_METHODS,
    INTERVAL_METHODS,
    MCL_METHODS,
    METHOD_LABELS,
    METHODS,
    STATUS_CODES,
    MethodTrace,
    RunResult,
    Task,
    run_one,
)

__all__ = [
    "CALIBRATION_COLUMNS", "COLUMNS", "DEFAULT_SCENARIOS", "FAULT_COLUMNS", "FAULT_METHODS",
    "INTERVAL_METHODS", "MCL_METHODS", "METHODS", "METHOD_LABELS", "RECOVERY_MAX_SLIP",
    "SCENARIOS", "STATUS_CODES", "EventOutcome", "FaultEvent", "MethodTrace", "RunResult",
    "Scenario", "Task", "aggregate", "calibration", "calibration_table", "evaluate",
    "event_outcomes", "fault_events", "fault_schedule", "figures", "main", "markdown_table",
    "metrics", "noticed", "run_one", "write_csv", "write_outputs",
]
