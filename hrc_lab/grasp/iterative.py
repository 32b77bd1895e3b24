"""Algorithm 4 on a single image: iterate the graspability check and the solution decoder until a graspable
object (or a call for help) is found, and score the answer against the labelling rule.

The decoder names part types ("move b and c"); the proposed objects are the nearest detected objects of those
types (image-plane box-centre distance, as :func:`hrc_lab.env.clutter.rule.resolve_request` resolves the rule's own
solutions), and they become the new request.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hrc_lab.env.clutter.rule import solution_types
from hrc_lab.grasp.solver import NodeReading

HELP = "help"


@dataclass
class IterativeAnswer:
    """The objects requested in turn, the solutions decoded on the way, and the final action."""

    requests: list[list[int]] = field(default_factory=list)
    solutions: list[list[str]] = field(default_factory=list)
    grasp: int | None = None  # node index to grasp; None with help (or no answer)
    help: bool = False


def nearest_of_types(boxes: np.ndarray, labels: list[str], current: int, types: list[str]) -> list[int]:
    """Per named type, the object of that type nearest to ``current`` (box-centre distance), excluding it."""
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    chosen = []
    for part_type in types:
        candidates = [j for j, label in enumerate(labels) if label == part_type and j != current]
        if candidates:
            chosen.append(min(candidates, key=lambda j: float(np.linalg.norm(centres[j] - centres[current]))))
    return chosen


def iterate(
    read: Callable[[np.ndarray], list[NodeReading]],
    boxes: np.ndarray,
    labels: list[str],
    goal_type: str,
    max_iterations: int,
) -> IterativeAnswer:
    """Algorithm 4. ``read(requested_mask)`` builds the scene graph with that request and returns the solver's
    reading of every node; at most ``max_iterations`` requests (``grasp.max_iterations``), after which the answer
    has neither a grasp nor help."""
    answer = IterativeAnswer()
    request = [i for i, label in enumerate(labels) if label == goal_type]
    seen: set[int] = set()
    while request and len(answer.requests) < max_iterations:
        answer.requests.append(request)
        seen.update(request)
        mask = np.zeros(len(labels), dtype=bool)
        mask[request] = True
        readings = read(mask)
        best = max(request, key=lambda i: readings[i].p_grasp)
        if readings[best].graspable:
            answer.grasp = best
            return answer
        tokens = readings[best].solution
        answer.solutions.append(tokens)
        if tokens == [HELP]:
            answer.help = True
            return answer
        request = [j for j in nearest_of_types(boxes, labels, best, solution_types(tokens)) if j not in seen]
    return answer
