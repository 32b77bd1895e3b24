"""Every report's plan (:mod:`hrc_lab.report.plan`), each defined beside its sections in its report module.

``hrc-lab-reproduce <topic>`` runs a plan's studies, then ``hrc-lab-report <topic>`` builds the report from their
runs; what is in no plan is in no report. An ablation is in a plan only when it explains a difference from the
thesis (its ``question``), about six per chapter at most; an investigation that is not worth a study goes into its
issue's note or a docs page (its command, without numbers).
"""

from __future__ import annotations

from hrc_lab.report.plan import Plan
from hrc_lab.report.sections import report_modules

CHAPTERS = ("ch3", "ch4", "ch5", "ch6", "data")


def _plans() -> dict[str, Plan]:
    found = [module.PLAN for module in report_modules()]
    return {plan.topic: plan for plan in sorted(found, key=lambda plan: CHAPTERS.index(plan.topic.split("_")[0]))}


PLANS: dict[str, Plan] = _plans()


def plan_of(topic: str) -> Plan:
    plan = PLANS[topic]
    plan.check()
    return plan
