"""Ch.6 protocols (Sec. 6.4.1): Table 6.1 (object accuracy for 1-3 requested types) and the single-image row of
Table 6.2 (Algorithm 4 on scenes of 3-6 parts). One job = (method, seed).

Rendered scenes and the trained detector depend on ``protocol.data_seed`` only and are cached under
``<paths.runs_dir>/cache/ch6`` (a file lock lets parallel sweep jobs share them), so every method and seed of a sweep
reads the same images through the same detector; ``seed`` fixes the requests and the solver's initialisation.
"""

from __future__ import annotations

import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.cache import cache_key, cached
from hrc_lab.env.clutter.spec import ClutterScene, ClutterSpec
from hrc_lab.experiments.context import RunContext
from hrc_lab.grasp import GRASPS
from hrc_lab.grasp.detection_metrics import detection_quality
from hrc_lab.grasp.detector_cache import detector_cache_key, load_or_train_detector
from hrc_lab.grasp.iterative import IterativeAnswer, iterate
from hrc_lab.grasp.observation import SceneNodes, scene_nodes
from hrc_lab.grasp.solver import GraspSolver

TRAIN, TEST, ITERATIVE = 1, 2, 3  # scene-seed streams


def scene_set(ctx: RunContext, spec: ClutterSpec, stream: int, count: int) -> list[ClutterScene]:
    from hrc_lab.env.clutter.scenes import generate_scenes, load_scenes, save_scenes

    seeds = [ctx.cfg.protocol.data_seed * 1_000_000 + stream * 100_000 + i for i in range(count)]
    key = cache_key([asdict(spec), seeds[0], count])
    path = Path(ctx.cfg.paths.runs_dir) / "cache" / "ch6" / f"scenes_{key}.npz"
    return load_scenes(cached(path, lambda p: save_scenes(p, generate_scenes(spec, seeds, progress=True))))


def detector_for(ctx: RunContext, train_scenes: list[ClutterScene]):
    """The detector trained on the training scenes, from the cache when another job already trained it."""
    cfg = ctx.cfg.grasp.detector
    key = detector_cache_key(cfg, [s.seed for s in train_scenes])
    cache_dir = Path(ctx.cfg.paths.runs_dir) / "cache" / "ch6"
    return load_or_train_detector(cfg, train_scenes, lambda: ctx.trainer("detector/"), cache_dir, key)


def random_request(rng: np.random.Generator, types: list[str], k: int | None = None) -> set[str] | None:
    present = sorted(set(types))
    k = int(rng.integers(1, len(present) + 1)) if k is None else k
    if k > len(present):
        return None
    return set(rng.choice(present, size=k, replace=False).tolist())


def object_accuracy(solver: GraspSolver, nodes: list[SceneNodes], requests: list[set[str] | None]) -> dict:
    """Object accuracy (6.4.1): a requested part counts when it is detected, its graspability is right and, when it
    is not graspable, so is the decoded solution. Also the graspability accuracy alone."""
    graphs, kept = [], []
    for n, request in zip(nodes, requests):
        if request is not None:
            graphs.append(solver.graph(n, n.requested(request)))
            kept.append((n, request))
    readings = solver.read(graphs) if graphs else []
    correct, grasp_correct = [], []
    for (n, request), reading in zip(kept, readings):
        node_of = {int(p): i for i, p in enumerate(n.truth) if p >= 0}
        for part, obj in enumerate(n.scene.objects):
            if obj.type not in request:
                continue
            node = node_of.get(part)
            if node is None:
                correct.append(False)
                grasp_correct.append(False)
                continue
            truth_grasp = bool(n.rule_graspable[part])
            grasp_ok = reading[node].graspable == truth_grasp
            grasp_correct.append(grasp_ok)
            correct.append(grasp_ok and (truth_grasp or reading[node].solution == n.rule_solution[part]))
    return {"oa": float(np.mean(correct)) if correct else float("nan"), "grasp_acc": float(np.mean(grasp_correct))}


def iterative_correct(spec: ClutterSpec, nodes: SceneNodes, goal_type: str, answer: IterativeAnswer) -> bool:
    """The final action of Algorithm 4 is right when it grasps a part the rule finds graspable: a requested part if
    any is graspable, else a part reached from a requested one through the rule's blockers (what has to be moved
    first, and what has to be moved before that...); when no such part exists, the answer must be help."""
    goals = [i for i, t in enumerate(nodes.scene.types) if t == goal_type]
    allowed = {g for g in goals if nodes.rule_graspable[g]}
    if not allowed:
        blocked_by = nodes.rule_blockers
        reached, frontier = set(goals), list(goals)
        while frontier:
            for part in blocked_by[frontier.pop()]:
                if part not in reached:
                    reached.add(part)
                    frontier.append(part)
        allowed = {p for p in reached if nodes.rule_graspable[p]}
        if not allowed:
            return answer.help
    return answer.grasp is not None and int(nodes.truth[answer.grasp]) in allowed


def prepare(ctx: RunContext):
    spec, protocol, cfg = ctx.cfg.env, ctx.cfg.protocol, ctx.cfg.grasp
    train = scene_set(ctx, spec, TRAIN, protocol.train_images)
    start = time.perf_counter()
    detector, info = detector_for(ctx, train)
    ctx.tracker.log_metrics({f"detector_{k}": float(v) for k, v in info.items() if isinstance(v, int | float)})
    solver = GRASPS.build(cfg, spec=spec, seed=ctx.seed)
    train_nodes = scene_nodes(spec, train, detector, cfg.detector, solver.needs_union_features)
    rng = ctx.rng(61)
    requests = [random_request(rng, n.labels or n.scene.types) for n in train_nodes]
    graphs = [solver.training_graph(n, r) for n, r in zip(train_nodes, requests) if r]
    solver.fit(graphs, ctx.trainer("solver/"))
    train_acc = object_accuracy(solver, train_nodes, requests)["grasp_acc"]
    return spec, protocol, detector, solver, train_acc, time.perf_counter() - start


def detector_metrics(ctx: RunContext, detector, scenes: list[ClutterScene]) -> dict[str, float]:
    """The detector on held-out scenes: mAP at IoU 0.5 (over detections scoring >= 0.05), recall and precision at
    ``grasp.detector.score_threshold``, and the share of scenes found exactly (``detector_*`` metrics)."""
    found = detector.detect([s.image for s in scenes], score_threshold=0.05)
    quality = detection_quality(found, [s.boxes for s in scenes], [s.types for s in scenes],
                                score_threshold=ctx.cfg.grasp.detector.score_threshold)
    return {f"detector_{k}": quality[k] for k in ("map", "recall", "precision", "scene_exact")}


def table_6_1(ctx: RunContext) -> dict[str, float]:
    spec, protocol, detector, solver, train_acc, seconds = prepare(ctx)
    test_scenes = scene_set(ctx, spec, TEST, protocol.test_images)
    test = scene_nodes(spec, test_scenes, detector, ctx.cfg.grasp.detector, solver.needs_union_features)
    rng = ctx.rng(62)
    metrics = {"train_grasp_acc": train_acc, "prepare_s": seconds, **detector_metrics(ctx, detector, test_scenes)}
    rows = []
    for k in protocol.request_sizes:
        result = object_accuracy(solver, test, [random_request(rng, n.scene.types, k) for n in test])
        metrics |= {f"oa_{k}": result["oa"], f"grasp_acc_{k}": result["grasp_acc"]}
        rows.append({"method": ctx.cfg.grasp.name, "seed": ctx.seed, "request_types": k, **result})
    ctx.tracker.log_table(pd.DataFrame(rows), "table_6_1")
    return metrics


def table_6_2_single(ctx: RunContext) -> dict[str, float]:
    spec, protocol, detector, solver, train_acc, _ = prepare(ctx)
    rng = ctx.rng(63)
    metrics, rows, examples = {"train_grasp_acc": train_acc}, [], []
    for count in protocol.object_counts:
        fixed = replace(spec, min_objects=count, max_objects=count)
        scenes = scene_set(ctx, fixed, ITERATIVE * 10 + count, protocol.cases)
        nodes = scene_nodes(fixed, scenes, detector, ctx.cfg.grasp.detector, solver.needs_union_features)
        outcomes = []
        for n in tqdm(nodes, desc=f"Algorithm 4, {count} objects", unit="scene"):
            goal_type = str(rng.choice(sorted(set(n.scene.types))))

            def read(mask, n=n):
                return solver.read([solver.graph(n, mask)])[0]

            answer = iterate(read, n.boxes, n.labels, goal_type, ctx.cfg.grasp.max_iterations)
            ok = iterative_correct(fixed, n, goal_type, answer)
            outcomes.append(ok)
            rows.append(
                {
                    "objects": count,
                    "goal": goal_type,
                    "iterations": len(answer.requests),
                    "solutions": " | ".join(" ".join(s) for s in answer.solutions),
                    "help": answer.help,
                    "correct": ok,
                }
            )
            if len(examples) < protocol.examples and (answer.solutions or len(examples) % 2):
                examples.append((n, goal_type, answer, ok))
        metrics[f"acc_{count}"] = float(np.mean(outcomes))
    ctx.tracker.log_table(pd.DataFrame(rows), "table_6_2_single")
    if examples:
        ctx.tracker.log_figure(example_figure(examples), "figures/examples.png")
        metrics["examples_logged"] = float(len(examples))
    return metrics


def example_figure(examples: list[tuple[SceneNodes, str, IterativeAnswer, bool]]):
    """Scenes with the requested type, every request of the iteration (boxes: green = grasped, orange = requested
    in turn, grey = other detections) and the decoded solutions."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    fig, axes = plt.subplots(1, len(examples), figsize=(3.2 * len(examples), 3.6), squeeze=False)
    for ax, (nodes, goal_type, answer, ok) in zip(axes[0], examples):
        ax.imshow(nodes.scene.image)
        requested = {i for request in answer.requests for i in request}
        for i, (box, label) in enumerate(zip(nodes.boxes, nodes.labels)):
            colour = "lime" if i == answer.grasp else "orange" if i in requested else "0.6"
            ax.add_patch(Rectangle(box[:2], *(box[2:] - box[:2]), fill=False, color=colour, lw=1.5))
            ax.text(box[0], box[1] - 1, label, color=colour, fontsize=8)
        steps = [" ".join(s) for s in answer.solutions] + (["help"] if answer.help and not answer.solutions else [])
        final = "help" if answer.help else f"grasp {nodes.labels[answer.grasp]}" if answer.grasp is not None else "-"
        ax.set_title(f"request {goal_type}: " + " → ".join([*steps, final]) + ("" if ok else " ✗"), fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    return fig
