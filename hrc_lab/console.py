"""What the console scripts print: third-party deprecation warnings and MLflow's store messages filtered, and a
job's one log line with its few headline metrics (every metric is in MLflow). The tests call the jobs' code directly
and still see the warnings (pytest's own ``filterwarnings`` decides there)."""

from __future__ import annotations

import logging
import os
import re
import warnings

# Warnings of these categories are the libraries' notes to their own users (torch.jit.script, Lightning's pytree,
# gymnasium's env registry ...): filtered, except where hrc_lab's own code raises them.
THIRD_PARTY = (DeprecationWarning, FutureWarning, PendingDeprecationWarning)
QUIET_LOGGERS = ("mlflow", "alembic", "lightning.pytorch.utilities.rank_zero", "lightning.fabric")


def quiet_third_party() -> None:
    """Filter third-party deprecation warnings and quiet MLflow's and Lightning's info lines in this process (the
    console scripts call it first; a sweep's workers, in ``hrc_lab.cli``, at the start of each job)."""
    for category in THIRD_PARTY:
        warnings.filterwarnings("ignore", category=category)
        warnings.filterwarnings("default", category=category, module=r"hrc_lab(\.|$)")
    # Lightning's notes on tiny in-memory data sets (a few batches, one process)
    warnings.filterwarnings("ignore", message=r".*(does not have many workers|smaller than the logging interval).*")
    os.environ.setdefault("MLFLOW_LOGGING_LEVEL", "WARNING")  # read when MLflow configures its loggers (workers too)
    for name in QUIET_LOGGERS:
        logging.getLogger(name).setLevel(logging.WARNING)


# A metric is a headline when its name is one of these (or one of these then "_<cell>"): what the report's thesis
# tables show. A job's log line names at most MAX_SHOWN of them; the rest are in MLflow.
HEADLINE = re.compile(r"^(sr|oa|ia|r2)(_.+)?$|^acc_\d+$|^(success_rate|final_policy_success_rate|"
                      r"expert_success_rate|ad_acc|sg_acc|sc_acc|detector_map|acc_o|acc_g)$")
MAX_SHOWN = 6


def headline(metrics: dict[str, float]) -> str:
    """``sr=0.980, sr_case1=1.000 (+14 more)``: a job's headline metrics for its log line."""
    shown = [key for key in metrics if HEADLINE.match(key)][:MAX_SHOWN]
    if not shown:
        shown = [key for key in metrics if not key.startswith(("n_", "fail_"))][:3]
    rest = len(metrics) - len(shown)
    text = ", ".join(f"{key}={metrics[key]:.3f}" for key in shown)
    return f"{text} (+{rest} more)" if rest else text
