"""Import cycles inside hrc_lab, from the source (every ``import hrc_lab...``, lazy and TYPE_CHECKING ones included):
between modules, then between its top-level parts (``hrc_lab.<subpackage>`` or ``hrc_lab.<module>``).

    .venv/bin/python scripts/import_cycles.py
"""

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1]


def imports() -> dict[str, set[str]]:
    found = {}
    for path in (ROOT / "hrc_lab").rglob("*.py"):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hrc_lab"):
                targets.add(node.module)
            elif isinstance(node, ast.Import):
                targets |= {alias.name for alias in node.names if alias.name.startswith("hrc_lab")}
        found[name] = targets
    return found


def part(module: str) -> str:
    return ".".join(module.split(".")[:2])


def main() -> None:
    found = imports()
    for level, key in (("modules", lambda m: m), ("parts", part)):
        graph = nx.DiGraph([(key(a), key(b)) for a, targets in found.items() for b in targets
                            if b in found and key(a) != key(b)])
        cycles = sorted(nx.simple_cycles(graph), key=len)
        print(f"import cycles between {level}: {len(cycles)}")
        for cycle in cycles:
            print("  " + " -> ".join([*cycle, cycle[0]]))


if __name__ == "__main__":
    main()
