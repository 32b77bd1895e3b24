"""Runs whose configuration today's command no longer composes: a default changed after they ran.

A report section names the command that re-runs it. When a default changes (e.g. Table 3.1's ``motion.steps``
2000 -> 6000), the runs made before the change still sit in the store under the same variant, and that command
would now compute something else. Each run's logged config (its ``param.<key>`` columns) is therefore compared with
the config its own overrides compose from today's ``conf/``; every setting that differs is *pinned*: added to the
run's variant overrides, as if it had been given on the command line. Such runs read as their own ablation section
("... — ablation: motion.steps=2000"), whose Reproduce line computes them again, and they share that section with
runs that are given the same override explicitly. Settings of the neutral groups (where a run logs and writes) are
never pinned, nor a protocol setting its schema marks as read only by other methods (``read_by``); a setting the run
did not log (a key added since) is compared as its schema default, the value that kept what ran before (pinned when an
experiment file now sets it otherwise); a run whose overrides no longer compose keeps its variant. The other way
round, an override that today's defaults already give (``motion.steps=6000`` once 6000 is the default) leaves the
run's variant: such a run is what today's command computes.
"""

from __future__ import annotations

import re

import pandas as pd

from hrc_lab.run_naming import variant_of
from hrc_lab.tracking import changed_settings, composed_today, schema_defaults_today

PARAM_PREFIX = "param."  # params (the resolved config, dotted keys) are columns "param.<key>"


def read_by_run(key: str, protocol: str | None, method: str | None) -> bool:
    """False for a protocol key its schema field marks as read only by other methods (``metadata={"read_by":
    (...)}``, e.g. Table 4.3's ``drl_demos``, which only DRL's runs read): its change does not change the run."""
    from dataclasses import fields

    from hrc_lab.experiments import PROTOCOLS

    if not key.startswith("protocol.") or protocol not in PROTOCOLS.names():
        return True
    name = key.split(".")[1]
    field = next((f for f in fields(PROTOCOLS.get(protocol).schema) if f.name == name), None)
    read_by = field.metadata.get("read_by") if field is not None else None
    return read_by is None or method in read_by


def _override_value(value: str) -> str:
    """A logged param as a Hydra override value: None as null, text with spaces or commas quoted."""
    if value == "None":
        return "null"
    return f"'{value}'" if re.search(r"[\s,\[\]{}()=:']", value) else value


def job_overrides(row: pd.Series) -> list[str] | None:
    """The overrides ``row``'s job was launched with, its experiment file named; None when they are not logged or
    the user's own config files were composed (not in today's ``conf/``)."""
    overrides = row.get("overrides")
    if not isinstance(overrides, str) or "--" in str(row.get("variant_overrides", "")):
        return None
    items = overrides.split()
    if not any(item.startswith("experiment=") for item in items) and isinstance(row.get("experiment"), str):
        items.insert(0, f"experiment={row['experiment']}")  # the experiment file the run's tag names
    return items


def redundant_overrides(row: pd.Series) -> list[str]:
    """The run's variant overrides that today's defaults already give (e.g. ``motion.steps=6000`` once 6000 is the
    default): without one of them its overrides compose the same config."""
    items = job_overrides(row)
    today = composed_today(tuple(items)) if items is not None else None
    if today is None:
        return []
    own = str(row.get("variant_overrides", "")).split()
    return [item for item in own if item in items
            and composed_today(tuple(other for other in items if other != item)) == today]


def _list_override(logged: dict[str, str], parent: str) -> str:
    """The list ``parent`` as its flattened params ``parent.0``, ``parent.1.0``, ... logged it: "[a,[b,c]]"."""
    indices = sorted({int(head) for key in logged if key.startswith(parent + ".")
                      for head in [key[len(parent) + 1:].split(".", 1)[0]] if head.isdigit()})
    return "[" + ",".join(_override_value(logged[f"{parent}.{i}"]) if f"{parent}.{i}" in logged
                          else _list_override(logged, f"{parent}.{i}") for i in indices) + "]"


def pinned_settings(row: pd.Series) -> list[str]:
    """The overrides (``key=value``) that give ``row``'s run the config it logged where today's defaults differ;
    a changed list element pins its whole list. Empty for a run without its ``overrides`` tag."""
    items = job_overrides(row)
    today = composed_today(tuple(items)) if items is not None else None
    if today is None:
        return []
    logged = {key[len(PARAM_PREFIX):]: value for key, value in row.items()
              if key.startswith(PARAM_PREFIX) and isinstance(value, str)}
    compared = {key: value for key, value in logged.items() if key in today}  # today holds no neutral settings
    defaults = schema_defaults_today(tuple(items))
    changed = [key for key in changed_settings(compared, today, defaults)
               if read_by_run(key, logged.get("protocol.name"), row.get("method"))]
    pins: dict[str, str] = {}
    for key in changed:
        parts = key.split(".")
        index = next((i for i, part in enumerate(parts) if part.isdigit()), None)
        if index is None:  # as logged, or, a key added since the run, its schema default
            pins[key] = _override_value(logged.get(key, defaults.get(key)))
            continue
        parent = ".".join(parts[:index])  # a list: pin all of it, as logged
        pins[parent] = _list_override(logged, parent)
    return [f"{key}={value}" for key, value in pins.items()]


def pin_changed_defaults(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (one row per run, :func:`hrc_lab.report.runs.fetch_runs`' columns) with each run whose logged
    config today's command would not give moved to the variant of its overrides plus the pinned settings, and each
    run's overrides that today's defaults already give left out of its variant (``variant``, ``variant_overrides``;
    a run whose only overrides were such is a default run); ``pinned``: the pinned settings,
    ``logged_variant_overrides``: the variant's overrides as the run logged them."""
    if frame.empty:
        return frame
    frame = frame.copy()
    pinned = [pinned_settings(row) for _, row in frame.iterrows()]
    redundant = [redundant_overrides(row) for _, row in frame.iterrows()]
    frame["pinned"] = [" ".join(pins) for pins in pinned]
    frame["logged_variant_overrides"] = frame["variant_overrides"]
    for i, (pins, same) in enumerate(zip(pinned, redundant, strict=True)):
        if not pins and not same:
            continue
        own = [item for item in str(frame.at[frame.index[i], "variant_overrides"]).split() if item not in same]
        keys = {item.split("=", 1)[0] for item in own}
        extra = own + [pin for pin in pins if pin.split("=", 1)[0] not in keys]
        variant, shown = variant_of(extra, sweep_keys=[])
        frame.at[frame.index[i], "variant"] = variant
        frame.at[frame.index[i], "variant_overrides"] = " ".join(shown)
    return frame
