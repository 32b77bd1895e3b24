"""Ch.6 protocols (Sec. 6.4): Table 6.1 (object accuracy for 1-3 requested types), the single-image row of Table 6.2
(Algorithm 4 on scenes of 3-6 parts), Table 6.3 (image-based accuracy on a data set in VMRD's layout) and Fig. 6.9
(the graspability's and the solutions' image-based accuracy over the number of object types). One job =
(method, seed).

Rendered scenes and the trained detector depend on ``protocol.data_seed`` only and are cached under
``<paths.runs_dir>/cache/ch6`` (a file lock lets parallel sweep jobs share them), so every method and seed of a sweep
reads the same images through the same detector; ``seed`` fixes the requests and the solver's initialisation.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.cache import cache_key, cached
from hrc_lab.env.clutter.rule import iterative_solution
from hrc_lab.env.clutter.spec import PART_TYPES, ClutterScene, ClutterSpec
from hrc_lab.grasp import GRASPS
from hrc_lab.grasp.detection_metrics import detection_quality
from hrc_lab.grasp.detector_cache import detector_cache_key, load_or_train_detector
from hrc_lab.grasp.diagnostics import FAILURE_CAUSES, SceneGeometry, failure_cause, scene_geometry
from hrc_lab.grasp.iterative import IterativeAnswer, iterate
from hrc_lab.grasp.observation import SceneNodes, scene_nodes
from hrc_lab.grasp.solver import GraspSolver
from hrc_lab.run_context import RunContext

TRAIN, TEST, ITERATIVE = 1, 2, 3  # scene-seed streams


def scene_set(ctx: RunContext, spec: ClutterSpec, stream: int, count: int) -> list[ClutterScene]:
    from hrc_lab.env.clutter.scenes import SCENE_FORMAT, generate_scenes, load_scenes, save_scenes

    seeds = [ctx.cfg.protocol.data_seed * 1_000_000 + stream * 100_000 + i for i in range(count)]
    key = cache_key([asdict(spec), seeds[0], count, SCENE_FORMAT])
    path = Path(ctx.cfg.paths.runs_dir) / "cache" / "ch6" / f"scenes_{key}.npz"
    return load_scenes(cached(path, lambda p: save_scenes(p, generate_scenes(spec, seeds, progress=True))))


def detector_for(ctx: RunContext, train_scenes: list[ClutterScene], classes: tuple[str, ...]):
    """The detector of ``classes`` trained on the training scenes, from the cache when another job already trained
    it."""
    cfg = ctx.cfg.grasp.detector
    key = detector_cache_key(cfg, classes, [s.seed for s in train_scenes])
    cache_dir = Path(ctx.cfg.paths.runs_dir) / "cache" / "ch6"
    return load_or_train_detector(cfg, classes, train_scenes, lambda: ctx.trainer("detector/"), cache_dir, key)


def observe(spec: ClutterSpec, scenes: list[ClutterScene], detector, cfg, solver,
            annotated_blockers: list[list[list[int]]] | None = None) -> list[SceneNodes]:
    """What ``solver`` sees of ``scenes``: :func:`scene_nodes` with the run's grasp config ``cfg`` (its detector
    reading and depth features) and the solver's need for union-box features."""
    return scene_nodes(spec, scenes, detector, cfg.detector, solver.needs_union_features, annotated_blockers,
                       cfg.depth_grid)


def random_request(rng: np.random.Generator, types: list[str], k: int | None = None) -> set[str] | None:
    present = sorted(set(types))
    k = int(rng.integers(1, len(present) + 1)) if k is None else k
    if k > len(present):
        return None
    return set(rng.choice(present, size=k, replace=False).tolist())


def training_requests(rng: np.random.Generator, types: list[str], k: int) -> list[set[str] | None]:
    """The requests one training scene carries: one :func:`random_request` when ``k`` is 1, else ``k`` distinct
    non-empty sets of its part types in random order (all of them when there are fewer)."""
    if k == 1:
        return [random_request(rng, types)]
    present = sorted(set(types))
    subsets = [set(c) for size in range(1, len(present) + 1) for c in itertools.combinations(present, size)]
    return [subsets[i] for i in rng.permutation(len(subsets))[:k]]


def part_outcomes(solver: GraspSolver, nodes: list[SceneNodes], requests: list[set[str] | None]) -> pd.DataFrame:
    """One row per requested part: its scene (index into ``nodes``), its type, whether it was detected, whether its
    graspability is right, whether it cannot be grasped (the rule's), whether it is detected with the right decoded
    solution, and whether it counts for the object accuracy (6.4.1: detected, graspability right and, when it is not
    graspable, the decoded solution right)."""
    graphs, kept = [], []
    for k, (n, request) in enumerate(zip(nodes, requests)):
        if request is not None:
            graphs.append(solver.graph(n, n.requested(request)))
            kept.append((k, n, request))
    readings = solver.read(graphs) if graphs else []
    rows = []
    for (k, n, request), reading in zip(kept, readings):
        node_of = {int(p): i for i, p in enumerate(n.truth) if p >= 0}
        for part, obj in enumerate(n.scene.objects):
            if obj.type not in request:
                continue
            node = node_of.get(part)
            truth_grasp = bool(n.rule_graspable[part])
            grasp_ok = node is not None and reading[node].graspable == truth_grasp
            solution_ok = node is not None and reading[node].solution == n.rule_solution[part]
            rows.append({"scene": k, "type": obj.type, "detected": node is not None, "grasp_ok": grasp_ok,
                         "ungraspable": not truth_grasp, "solution_ok": solution_ok,
                         "correct": grasp_ok and (truth_grasp or solution_ok)})
    return pd.DataFrame(rows, columns=["scene", "type", "detected", "grasp_ok", "ungraspable", "solution_ok",
                                       "correct"])


def object_accuracy(outcomes: pd.DataFrame) -> dict[str, float]:
    """``oa``: the object accuracy; ``grasp_acc``: graspability right over every requested part (an undetected part
    counts as wrong); ``fit_acc``: graspability right over the detected ones, the solver's own accuracy;
    ``detected``: the share of requested parts detected."""
    if outcomes.empty:
        return {key: float("nan") for key in ("oa", "grasp_acc", "fit_acc", "detected")}
    found = outcomes[outcomes.detected]
    return {
        "oa": float(outcomes.correct.mean()),
        "grasp_acc": float(outcomes.grasp_ok.mean()),
        "fit_acc": float(found.grasp_ok.mean()) if len(found) else float("nan"),
        "detected": float(outcomes.detected.mean()),
    }


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


def prepare(ctx: RunContext, train: list[ClutterScene] | None = None,
            train_blockers: list[list[list[int]]] | None = None, classes: tuple[str, ...] = PART_TYPES,
            detector=None, stage: str = "solver/"):
    """The detector and the solver of ``classes`` trained on ``train`` (default: the protocol's rendered training
    scenes of our part types, labelled by the rule; else a data set's scenes with their ``train_blockers``,
    :func:`scene_nodes`, and its classes). ``detector``: one trained already (Fig. 6.9 reads each of its data sets
    through the whole data set's), else trained on ``train``; ``stage``: the solver's MLflow prefix."""
    spec, protocol, cfg = ctx.cfg.env, ctx.cfg.protocol, ctx.cfg.grasp
    train = scene_set(ctx, spec, TRAIN, protocol.train_images) if train is None else train
    start = time.perf_counter()
    if detector is None:
        detector, info = detector_for(ctx, train, classes)
        ctx.tracker.log_metrics({f"detector_{k}": float(v) for k, v in info.items() if isinstance(v, int | float)})
    solver = GRASPS.build(cfg, spec=spec, classes=classes, seed=ctx.seed)
    train_nodes = observe(spec, train, detector, cfg, solver, train_blockers)
    rng = ctx.rng(61)
    requests = [training_requests(rng, n.labels or n.scene.types, protocol.train_requests) for n in train_nodes]
    graphs = [solver.training_graph(n, r) for n, drawn in zip(train_nodes, requests) for r in drawn if r]
    solver.fit(graphs, ctx.trainer(stage))
    train = object_accuracy(part_outcomes(solver, train_nodes, [drawn[0] for drawn in requests]))
    train_metrics = {"train_grasp_acc": train["fit_acc"], "train_part_grasp_acc": train["grasp_acc"],
                     "train_detected": train["detected"], "prepare_s": time.perf_counter() - start}
    return spec, protocol, detector, solver, train_metrics


def detector_metrics(ctx: RunContext, detector, scenes: list[ClutterScene]) -> dict[str, float]:
    """The detector on held-out scenes: mAP at IoU 0.5 (over detections scoring >= 0.05), recall and precision at
    ``grasp.detector.score_threshold``, and the share of scenes found exactly (``detector_*`` metrics)."""
    found = detector.detect([s.image for s in scenes], score_threshold=0.05)
    quality = detection_quality(found, [s.boxes for s in scenes], [s.types for s in scenes],
                                score_threshold=ctx.cfg.grasp.detector.score_threshold)
    return {f"detector_{k}": quality[k] for k in ("map", "recall", "precision", "scene_exact")}


def table_6_1(ctx: RunContext) -> dict[str, float]:
    spec, protocol, detector, solver, metrics = prepare(ctx)
    test_scenes = scene_set(ctx, spec, TEST, protocol.test_images)
    test = observe(spec, test_scenes, detector, ctx.cfg.grasp, solver)
    rng = ctx.rng(62)
    metrics |= detector_metrics(ctx, detector, test_scenes)
    rows, every = [], []
    for k in protocol.request_sizes:
        outcomes = part_outcomes(solver, test, [random_request(rng, n.scene.types, k) for n in test])
        result = object_accuracy(outcomes)
        metrics |= {f"{key}_{k}": value for key, value in result.items()}  # oa_k, grasp_acc_k, fit_acc_k, detected_k
        rows.append({"method": ctx.cfg.grasp.name, "seed": ctx.seed, "request_types": k, **result})
        every.append(outcomes.assign(request_types=k))
    outcomes = pd.concat(every, ignore_index=True)
    for part_type, part in outcomes.groupby("type"):  # 6.4.1: a request of part "a" is the hardest, OA ~ 0.81
        metrics[f"oa_type_{part_type}"] = float(part.correct.mean())
    geometry = scene_geometry(test, ctx.cfg.grasp.distance_filter)
    metrics |= geometry.metrics(ctx.cfg.grasp.distance_filter)
    ctx.tracker.log_table(pd.DataFrame(rows), "table_6_1")
    ctx.tracker.log_table(outcomes, "part_outcomes")
    ctx.tracker.log_figure(geometry_figure(geometry, ctx.cfg.grasp.distance_filter), "figures/geometry.png")
    return metrics


def table_6_2_single(ctx: RunContext) -> dict[str, float]:
    spec, protocol, detector, solver, metrics = prepare(ctx)
    rng = ctx.rng(63)
    rows, examples = [], []
    for count in protocol.object_counts:
        fixed = replace(spec, min_objects=count, max_objects=count)
        scenes = scene_set(ctx, fixed, ITERATIVE * 10 + count, protocol.cases)
        nodes = observe(fixed, scenes, detector, ctx.cfg.grasp, solver)
        outcomes, causes = [], []
        for n in tqdm(nodes, desc=f"Algorithm 4, {count} objects", unit="scene"):
            goal_type = str(rng.choice(sorted(set(n.scene.types))))
            readings = []

            def read(mask, n=n, readings=readings):
                readings.append(solver.read([solver.graph(n, mask)])[0])
                return readings[-1]

            answer = iterate(read, n.boxes, n.labels, goal_type, ctx.cfg.grasp.max_iterations)
            ok = iterative_correct(fixed, n, goal_type, answer)
            goals = [i for i, t in enumerate(n.scene.types) if t == goal_type]
            rule_requests = min(len(iterative_solution(fixed, n.scene, g)) for g in goals)
            cause = "" if ok else failure_cause(n, goal_type, answer, readings)
            outcomes.append(ok)
            causes.append(cause)
            rows.append(
                {
                    "objects": count,
                    "goal": goal_type,
                    "iterations": len(answer.requests),
                    "rule_requests": rule_requests,  # the rule's own Algorithm 4 from the nearest-to-solve goal part
                    "solutions": " | ".join(" ".join(s) for s in answer.solutions),
                    "help": answer.help,
                    "correct": ok,
                    "failure": cause,
                }
            )
            if len(examples) < protocol.examples and (answer.solutions or len(examples) % 2):
                examples.append((n, goal_type, answer, ok))
        metrics[f"acc_{count}"] = float(np.mean(outcomes))
        metrics |= {f"fail_{cause}_{count}": causes.count(cause) / len(causes) for cause in FAILURE_CAUSES}
    ctx.tracker.log_table(pd.DataFrame(rows), "table_6_2_single")
    if examples:
        ctx.tracker.log_figure(example_figure(examples), "figures/examples.png")
        metrics["examples_logged"] = float(len(examples))
    return metrics


def table_6_2_robot(ctx: RunContext) -> dict[str, float]:
    """The robot row of Table 6.2: the single-image row's scenes and requested types (same seeds and draws), each an
    episode of :func:`hrc_lab.grasp.robot_grasping.run_episode` in the robot cell."""
    from hrc_lab.env.robot.clutter_cell import ClutterCell
    from hrc_lab.grasp.diagnostics import ROBOT_FAILURES
    from hrc_lab.grasp.robot_grasping import run_episode

    spec, protocol, detector, solver, metrics = prepare(ctx)
    cfg = ctx.cfg.grasp
    cell = ClutterCell(spec, seed=ctx.seed, grip_depth=protocol.grip_depth)
    rng = ctx.rng(63)  # the single-image row's stream: the same requested type for each scene

    def episode_of(cell, scene, fixed, goal, on_decision=None):
        return run_episode(
            cell, scene, fixed, goal,
            perceive=lambda now: observe(fixed, [now], detector, cfg, solver)[0],
            read=lambda nodes, mask: solver.read([solver.graph(nodes, mask)])[0],
            max_requests=cfg.max_iterations, max_grasps=protocol.max_grasps,
            answer_right=lambda nodes, goal, answer: iterative_correct(fixed, nodes, goal, answer),
            on_decision=on_decision, preshape=protocol.preshape, choose_yaw=protocol.choose_yaw,
            yaw_order=protocol.yaw_order,
        )

    episodes, steps, shown = [], [], None
    try:
        for count in protocol.object_counts:
            fixed = replace(spec, min_objects=count, max_objects=count)
            scenes = scene_set(ctx, fixed, ITERATIVE * 10 + count, protocol.cases)
            outcomes, causes = [], []
            for k, scene in enumerate(tqdm(scenes, desc=f"Algorithm 4 with the robot, {count} objects", unit="scene")):
                goal = str(rng.choice(sorted(set(scene.types))))
                episode = episode_of(cell, scene, fixed, goal)
                if shown is None and episode.success and count == protocol.video_objects:
                    shown = (scene, fixed, goal, k)
                outcomes.append(episode.success)
                causes.append(episode.failure)
                episodes.append({"objects": count, "scene": k, "goal": goal, "success": episode.success,
                                 "failure": episode.failure, "grasps": sum(s.held is not None for s in episode.steps),
                                 "iterations": len(episode.steps)})
                steps += [{"objects": count, "scene": k, "iteration": i, "action": s.action, "right": s.right,
                           "cause": s.cause, "held": s.held or "", "disturbed": s.disturbed, "yaw_deg": s.yaw_deg,
                           "grip_mm": s.grip_mm,
                           "requests": " | ".join(" ".join(r) for r in s.requests),
                           "solutions": " | ".join(" ".join(w) for w in s.solutions),
                           **{f"{phase}_ms": 1000 * v for phase, v in s.seconds.items()}}
                          for i, s in enumerate(episode.steps)]
            metrics[f"acc_{count}"] = float(np.mean(outcomes))
            metrics |= {f"fail_{cause}_{count}": causes.count(cause) / len(causes) for cause in ROBOT_FAILURES}
    finally:
        cell.close()
    if shown is not None:
        metrics["video_scene"] = float(shown[3])
        for path in robot_video(ctx, episode_of, *shown[:3]):
            ctx.tracker.log_artifact(path, "videos")
    steps_table = pd.DataFrame(steps)
    for phase in ("render", "detection", "reasoning"):
        metrics[f"{phase}_ms"] = float(steps_table[f"{phase}_ms"].mean())
    grasped = steps_table[steps_table.action.str.startswith("grasp")]
    metrics["motion_ms"] = float(grasped.motion_ms.mean()) if len(grasped) else float("nan")  # per grasp + put
    metrics["perception_reasoning_ms"] = float(steps_table[["render_ms", "detection_ms", "reasoning_ms"]].sum(1).mean())
    ctx.tracker.log_table(pd.DataFrame(episodes), "robot_episodes")
    ctx.tracker.log_table(steps_table, "robot_steps")
    return metrics


def robot_video(ctx: RunContext, episode_of, scene: ClutterScene, spec: ClutterSpec, goal: str) -> list[Path]:
    """One episode again, filmed from the cell's side camera with each decision as the caption
    (``robot_episode.mp4`` and its strip)."""
    from hrc_lab.env.robot.clutter_cell import ClutterCell
    from hrc_lab.env.robot.recorder import FrameRecorder, save_video
    from hrc_lab.env.robot.settings import CELL_CAMERA

    cell = ClutterCell(spec, seed=ctx.seed, render=True, grip_depth=ctx.cfg.protocol.grip_depth)
    try:
        recorder = FrameRecorder(cell, CELL_CAMERA, 480, 360, frame_skip=2)
        cell.on_step = recorder.tick

        def caption(step):
            recorder.text = f"request {goal}: " + " -> ".join([*(" ".join(s) for s in step.solutions), step.action])

        episode = episode_of(cell, scene, spec, goal, on_decision=caption)
        recorder.text = "delivered" if episode.success else f"failed: {episode.failure}"
        recorder.frames.append(recorder.frame())
        fps = cell.control_freq / recorder.frame_skip
        return save_video(recorder.frames, ctx.output_dir / "robot_episode.mp4", fps)
    finally:
        cell.close()


def vmrd_root(ctx: RunContext) -> Path:
    """``env.vmrd_root``, or the protocol's rendered scenes written in VMRD's layout (:func:`written_vmrd`)."""
    if ctx.cfg.env.vmrd_root is not None:
        return Path(ctx.cfg.env.vmrd_root)
    return written_vmrd(ctx, ctx.cfg.env.clutter())


def written_vmrd(ctx: RunContext, spec: ClutterSpec) -> Path:
    """The protocol's rendered scenes of ``spec`` written in VMRD's layout (their rule blockers as each part's
    children) under ``<paths.runs_dir>/cache/ch6/vmrd_<key>``, once for every job."""
    from hrc_lab.data.vmrd import write_vmrd
    from hrc_lab.env.clutter.rule import blockers

    protocol = ctx.cfg.protocol
    splits = {"trainval": scene_set(ctx, spec, TRAIN, protocol.train_images),
              "test": scene_set(ctx, spec, TEST, protocol.test_images)}
    children = {split: [blockers(spec, s) for s in scenes] for split, scenes in splits.items()}
    key = cache_key([asdict(spec), {split: [s.seed for s in scenes] for split, scenes in splits.items()}])
    path = Path(ctx.cfg.paths.runs_dir) / "cache" / "ch6" / f"vmrd_{key}"
    return cached(path, lambda partial: write_vmrd(partial, splits, children))


def dataset_classes(images) -> tuple[str, ...]:
    """The classes of a data set's images, sorted: the detector's classes and the solver's object labels."""
    return tuple(sorted({t for a in images for t in a.scene.types}))


def image_accuracy(outcomes: pd.DataFrame, objects: list[int]) -> dict[str, float]:
    """``ia``: the share of images whose every object is right (6.4.2); ``ia_<n>``: the same over the images of n
    objects (``objects[k]``: how many image k holds); ``oa``: the share of objects right."""
    per_image = outcomes.groupby("scene").correct.all()
    counts = pd.Series(objects).loc[per_image.index]
    metrics = {"ia": float(per_image.mean()), "oa": float(outcomes.correct.mean())}
    metrics |= {f"ia_{n}": float(per_image[counts == n].mean()) for n in sorted(counts.unique())}
    return metrics


def table_6_3(ctx: RunContext) -> dict[str, float]:
    from hrc_lab.data.vmrd import read_vmrd

    root, size = vmrd_root(ctx), ctx.cfg.env.image_size
    train, test = read_vmrd(root, "trainval", size), read_vmrd(root, "test", size)
    classes = dataset_classes(train + test)
    spec, _, detector, solver, metrics = prepare(ctx, [a.scene for a in train], [a.children for a in train], classes)
    test_scenes = [a.scene for a in test]
    nodes = observe(spec, test_scenes, detector, ctx.cfg.grasp, solver, [a.children for a in test])
    outcomes = part_outcomes(solver, nodes, [set(s.types) for s in test_scenes])  # every object of every image
    objects = [len(s.objects) for s in test_scenes]
    metrics |= image_accuracy(outcomes, objects) | detector_metrics(ctx, detector, test_scenes)
    metrics |= {"trainval_images": float(len(train)), "test_images": float(len(test)), "classes": float(len(classes)),
                "written_by_hrc_lab": float(ctx.cfg.env.vmrd_root is None)}
    images = outcomes.groupby("scene").correct.all().rename("correct").reset_index()
    images["image_id"] = [test[k].image_id for k in images.scene]
    images["objects"] = [objects[k] for k in images.scene]
    ctx.tracker.log_table(images, "images")
    ctx.tracker.log_table(outcomes, "part_outcomes")
    return metrics


def fewer_types(spec: ClutterSpec, k: int) -> ClutterSpec:
    """``spec`` with only its k most numerous part types (largest ``max_counts``, ties by name): the others' counts
    0, the object counts capped at the parts left (a alone: 3 parts)."""
    kept = sorted((t for t, n in spec.max_counts.items() if n > 0), key=lambda t: (-spec.max_counts[t], t))[:k]
    counts = {t: n if t in kept else 0 for t, n in spec.max_counts.items()}
    most = min(spec.max_objects, sum(counts.values()))
    return replace(spec, max_counts=counts, max_objects=most, min_objects=min(spec.min_objects, most))


def type_subsets(ctx: RunContext, train: list, test: list) -> dict[int, tuple[list, list]]:
    """Fig. 6.9's data sets, per k in ``protocol.type_counts``: (trainval, test) images of k object types. On our
    scenes (``train``/``test`` written by :func:`vmrd_root`) the scenes of :func:`fewer_types` rendered and written
    the same way; on ``env.vmrd_root`` its images whose objects are all of its k most frequent training classes."""
    from hrc_lab.data.vmrd import read_vmrd

    size, counts = ctx.cfg.env.image_size, ctx.cfg.protocol.type_counts
    if ctx.cfg.env.vmrd_root is None:
        roots = {k: written_vmrd(ctx, fewer_types(ctx.cfg.env.clutter(), k)) for k in counts}
        return {k: (read_vmrd(root, "trainval", size), read_vmrd(root, "test", size)) for k, root in roots.items()}
    frequency = pd.Series([t for a in train for t in a.scene.types]).value_counts()
    ranked = sorted(frequency.index, key=lambda t: (-frequency[t], t))
    if max(counts) > len(ranked):
        raise ValueError(f"protocol.type_counts must be values in 1..{len(ranked)} (the classes of the training "
                         f"images of {ctx.cfg.env.vmrd_root}), got {counts}")
    subsets = {}
    for k in counts:
        kept = set(ranked[:k])
        subsets[k] = tuple([a for a in split if set(a.scene.types) <= kept] for split in (train, test))
        if not all(subsets[k]):
            raise ValueError(f"protocol.type_counts: {ctx.cfg.env.vmrd_root} has no trainval or no test image whose "
                             f"objects are all of its {k} most frequent classes {sorted(kept)}")
    return subsets


def component_accuracy(outcomes: pd.DataFrame, objects: list[int]) -> dict[str, float]:
    """Fig. 6.9's image-based accuracies of the two stages (every object of every image requested):
    ``grasp_ia``, the share of images whose every object is detected with the right graspability (the GNN's
    classification); ``solution_ia``, over the images holding an object that cannot be grasped, the share whose every
    such object is detected and decoded to the right solution (LSTM_Att); each also as ``<name>_n<n>`` over the
    images of n objects (``objects[k]``: how many image k holds)."""
    grasp = outcomes.groupby("scene").grasp_ok.all()
    solution = outcomes[outcomes.ungraspable].groupby("scene").solution_ok.all()
    counts = pd.Series(objects)
    metrics = {}
    for name, per_image in (("grasp_ia", grasp), ("solution_ia", solution)):
        metrics[name] = float(per_image.mean()) if len(per_image) else float("nan")
        sizes = counts.loc[per_image.index]
        metrics |= {f"{name}_n{n}": float(per_image[sizes == n].mean()) for n in sorted(sizes.unique())}
    metrics["solution_images"] = float(len(solution))
    return metrics


def fig_6_9(ctx: RunContext) -> dict[str, float]:
    """For each k in ``protocol.type_counts``: a solver trained on the k-type data set's trainval images, read
    through the whole data set's detector (Table 6.3's), scored on its test images (metrics ``types<k>_<name>``:
    :func:`component_accuracy`, Table 6.3's ``ia`` and ``oa``, the training fit and the data set's sizes)."""
    from hrc_lab.data.vmrd import read_vmrd

    root, size = vmrd_root(ctx), ctx.cfg.env.image_size
    train, test = read_vmrd(root, "trainval", size), read_vmrd(root, "test", size)
    classes = dataset_classes(train + test)
    detector, info = detector_for(ctx, [a.scene for a in train], classes)
    metrics = {f"detector_{k}": float(v) for k, v in info.items() if isinstance(v, int | float)}
    metrics |= {"classes": float(len(classes)), "written_by_hrc_lab": float(ctx.cfg.env.vmrd_root is None)}
    rows = []
    for k, (k_train, k_test) in type_subsets(ctx, train, test).items():
        spec, _, _, solver, fit = prepare(ctx, [a.scene for a in k_train], [a.children for a in k_train], classes,
                                          detector, stage=f"solver_{k}types/")
        scenes = [a.scene for a in k_test]
        nodes = observe(spec, scenes, detector, ctx.cfg.grasp, solver, [a.children for a in k_test])
        outcomes = part_outcomes(solver, nodes, [set(s.types) for s in scenes])
        objects = [len(s.objects) for s in scenes]
        table = image_accuracy(outcomes, objects)
        result = component_accuracy(outcomes, objects) | {"ia": table["ia"], "oa": table["oa"]}
        result |= {"train_grasp_acc": fit["train_grasp_acc"], "trainval_images": float(len(k_train)),
                   "test_images": float(len(k_test)), "objects": float(np.mean(objects))}
        metrics |= {f"types{k}_{name}": value for name, value in result.items()}
        rows.append({"types": k, "classes": " ".join(sorted({t for s in scenes for t in s.types})), **result})
    ctx.tracker.log_table(pd.DataFrame(rows), "fig_6_9")
    return metrics


def geometry_figure(geometry: SceneGeometry, threshold: float):
    """Histograms of the normalised centre distance of every part pair and of the pairs the rule links (a blocker
    and the part it blocks), with GNN_DF_Att's distance filter."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3))
    bins = np.linspace(0, max(0.5, float(geometry.pair_distance.max(initial=0))), 40)
    ax.hist(geometry.pair_distance, bins, density=True, alpha=0.5, label="every pair of parts")
    ax.hist(geometry.pair_distance[geometry.pair_blocks], bins, density=True, alpha=0.5,
            label="a blocker and the part it blocks")
    ax.axvline(threshold, color="k", linestyle="--", linewidth=1, label=f"distance filter {threshold:g}")
    ax.set_xlabel("box-centre distance / image side")
    ax.set_ylabel("density")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


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
