"""mkdocs hooks: pages generated from the code at build time, so they cannot drift from it.

- ``config_groups.md``: every config group's keys (field, type, default, the comment written beside the field)
  from the dataclass schemas registered in hrc_lab's registries (the schemas Hydra's ConfigStore holds as
  ``schema/<group>/<name>``), plus which ``conf/<group>/*.yaml`` file sets which keys.
- ``cli.md``: the ``--help`` text of every console script of ``pyproject.toml``.

Registered in ``mkdocs.yml`` (``hooks:``); imports no simulator (the registries import schemas only).
"""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import importlib
import inspect
import io
import tokenize
import typing
from pathlib import Path

import yaml
from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------------------------------------------- config groups
def _field_comments(cls: type) -> dict[str, str]:
    """Field name -> the comment beside it (``x: int = 1  # ...``), the comment lines right above it, or the
    string literal right below it, from the class' source (and its dataclass bases')."""
    comments: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass) or klass is object:
            continue
        try:
            lines, _ = inspect.getsourcelines(klass)
        except (OSError, TypeError):
            continue
        source = inspect.cleandoc("\n" + "".join(lines)) if lines[0].startswith(" ") else "".join(lines)
        tree = ast.parse(source)
        line_comments: dict[int, str] = {}
        for token in tokenize.generate_tokens(io.StringIO(source).readline):
            if token.type == tokenize.COMMENT:
                line_comments[token.start[0]] = token.string.lstrip("#").strip()
        src_lines = source.splitlines()
        body = tree.body[0].body
        for i, node in enumerate(body):
            if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
                continue
            parts = []
            above, k = [], node.lineno - 1
            while k >= 1 and src_lines[k - 1].strip().startswith("#"):
                above.insert(0, line_comments.get(k, ""))
                k -= 1
            parts += above
            end = node.end_lineno or node.lineno
            for line in range(node.lineno, end + 1):
                if line in line_comments and not src_lines[line - 1].strip().startswith("#"):
                    parts.append(line_comments[line])
            nxt = body[i + 1] if i + 1 < len(body) else None
            if isinstance(nxt, ast.Expr) and isinstance(getattr(nxt, "value", None), ast.Constant) \
                    and isinstance(nxt.value.value, str):
                parts.append(inspect.cleandoc(nxt.value.value))
            comments[node.target.id] = " ".join(p for p in parts if p)
    return comments


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _code(text: str) -> str:  # a pipe inside a code span does not split a table cell (Python-Markdown's tables)
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def _default(field: dataclasses.Field) -> object:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return field.default_factory()  # type: ignore[misc]
    return dataclasses.MISSING


def _rows(cls: type, prefix: str = "", instance: object = None) -> list[str]:
    """One table row per field; a nested dataclass' keys follow it, with the defaults of the parent's instance."""
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # a forward reference that does not resolve: show the annotations as written
        hints = {}
    comments = _field_comments(cls)
    rows = []
    for field in dataclasses.fields(cls):
        if not field.init:
            continue
        kind = hints.get(field.name)
        default = getattr(instance, field.name) if instance is not None else _default(field)
        written = field.type if isinstance(field.type, str) else getattr(field.type, "__name__", str(field.type))
        if isinstance(kind, type) and dataclasses.is_dataclass(kind):
            rows.append(f"| `{prefix}{field.name}` | `{kind.__name__}` | (its keys below) | "
                        f"{_cell(comments.get(field.name, ''))} |")
            rows += _rows(kind, f"{prefix}{field.name}.", None if default is dataclasses.MISSING else default)
            continue
        shown = "required" if default is dataclasses.MISSING else _code(repr(default))
        rows.append(f"| `{prefix}{field.name}` | {_code(written)} | {shown} | {_cell(comments.get(field.name, ''))} |")
    return rows


def _schema_section(cls: type, names: list[str], level: str = "###") -> list[str]:
    out = [f"{level} `{cls.__module__}.{cls.__qualname__}`", ""]
    if names:
        out += [f"Registered as: {', '.join(f'`{n}`' for n in names)}.", ""]
    doc = inspect.getdoc(cls)
    if doc and not doc.startswith(cls.__name__ + "("):  # dataclasses' generated signature is no docstring
        out += [doc, ""]
    out += ["| key | type | default | note |", "|---|---|---|---|", *_rows(cls), ""]
    return out


def _conf_files(group: str) -> list[str]:
    folder = ROOT / "conf" / group
    if not folder.is_dir():
        return []
    out = ["| file | `name` | keys it sets (everything else is the schema's default) |", "|---|---|---|"]
    for path in sorted(folder.glob("*.yaml")):
        data = yaml.safe_load(path.read_text()) or {}
        keys = [k for k in data if k not in ("defaults", "name")]
        bases = [d for d in data.get("defaults", []) if isinstance(d, str) and d != "_self_"]
        extends = f" (extends {', '.join(f'`{b}`' for b in bases)})" if bases else ""
        out.append(f"| `conf/{group}/{path.name}` | `{data.get('name', '')}` | "
                   f"{', '.join(f'`{k}`' for k in keys) or '—'}{extends} |")
    return out + [""]


def config_groups_page() -> str:
    from hrc_lab.config import PathsConfig, TrainerConfig, group_registries
    from hrc_lab.experiments import PROTOCOLS

    out = [
        "# Config groups and keys",
        "",
        "Generated from the dataclass schemas when the documentation is built (`docs/hooks.py`), so it cannot drift "
        "from the code. Each group's implementations are registered in `hrc_lab` (name -> schema, implementation); "
        "the schemas are in Hydra's ConfigStore as `schema/<group>/<name>`, so every key below can be overridden "
        "from the command line without `+`, e.g. `reasoning.hidden=128`. A file in `conf/<group>/` names only what "
        "differs from its schema's defaults. How to choose and override: [Configuration](configuration.md).",
        "",
    ]
    groups = {**group_registries(), "protocol": PROTOCOLS}
    order = ["env", "reasoning", "motion", "perception", "grasp", "rl", "tamp", "protocol", "logger"]
    for group in order:
        registry = groups[group]
        out += [f"## `{group}`", ""]
        if group == "protocol":
            out += ["Set by each experiment file (`conf/experiment/<chapter>/<table>.yaml`, key `protocol`, which "
                    "extends `schema/protocol/<name>`).", ""]
        by_schema: dict[type, list[str]] = {}
        for name in registry.names():
            by_schema.setdefault(registry.get(name).schema, []).append(name)
        for schema, names in by_schema.items():
            out += _schema_section(schema, names)
        if group != "protocol":
            out += ["### Files", "", *_conf_files(group)]
    out += ["## `trainer`", "", *_schema_section(TrainerConfig, [], "###")[2:], "### Files", "",
            *_conf_files("trainer")]
    out += ["## `paths`", "", *_schema_section(PathsConfig, [], "###")[2:], "### Files", "", *_conf_files("paths")]
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------------------------------------- CLIs
CLIS = [  # console script, module, the argument lists whose --help is shown
    ("hrc-lab-reproduce", "hrc_lab.reproduce", [[]]),
    ("hrc-lab-report", "hrc_lab.report.cli", [[]]),
    ("hrc-lab-runs", "hrc_lab.runs_cli", [[], ["stale"]]),
    ("hrc-lab-server", "hrc_lab.server", [[], ["start"], ["stop"], ["status"]]),
]


def _help(module: str, args: list[str]) -> str:
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer), contextlib.suppress(SystemExit):
        importlib.import_module(module).main([*args, "--help"])
    return buffer.getvalue().rstrip()


def cli_page() -> str:
    cli_doc = ast.get_docstring(ast.parse((ROOT / "hrc_lab" / "cli.py").read_text()))
    out = [
        "# Command-line tools",
        "",
        "The console scripts of `pyproject.toml` (`.venv/bin/<name>`). Generated when the documentation is built "
        "(`docs/hooks.py`): `hrc-lab`'s text is the docstring of `hrc_lab/cli.py`, the others' is their `--help`.",
        "",
        "## `hrc-lab`",
        "",
        "A Hydra application: `hrc-lab --help` lists the config groups, "
        "`hrc-lab experiment=<chapter>/<table> --cfg job` prints the composed config. "
        "See [Running experiments](running.md) and [Configuration](configuration.md).",
        "",
        "```text",
        cli_doc or "",
        "```",
        "",
    ]
    for name, module, arg_lists in CLIS:
        out += [f"## `{name}`", ""]
        for args in arg_lists:
            if args:
                out += [f"`{name} {' '.join(args)} --help`:", ""]
            out += ["```text", _help(module, args), "```", ""]
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------------------------------------- hooks
def on_files(files, config):
    for path, make in (("config_groups.md", config_groups_page), ("cli.md", cli_page)):
        files.append(File.generated(config, path, content=make()))
    return files
