"""What Table 6.1's graspability can be read from, on ground-truth boxes (issue 47): gradient-boosted classifiers
trained on Table 6.1's training scenes and scored on its test scenes (the protocol's seeds; scenes from the run
cache, rendered when missing), each on one set of inputs:

- per part, its depth features (``grasp.depth_grid`` 4: heights in its box and in the rule's finger volumes);
- per pair (does j block i?), the pair's box geometry and both types (``hrc_lab.grasp.graph.pair_geometry``), and
  the same with both parts' depth features; a part is read graspable when no pair says it is blocked, and, when
  it is not graspable, its solution from the predicted blockers' types.

Prints each one's graspability accuracy on the test parts (per part type) and, for the pair classifiers, the share
of ungraspable parts whose solution comes out right. The bounds docs/chapters/ch6.md quotes for
``grasp=gnn_rel_att_depth``:

    .venv/bin/python scripts/ch6_relation_bounds.py   # ~2 min on a free core once the scenes are cached
"""

import argparse
from types import SimpleNamespace

import numpy as np
from hydra import compose, initialize_config_dir
from sklearn.ensemble import GradientBoostingClassifier

import hrc_lab.cli  # noqa: F401  (registers the config schemas)
from hrc_lab.config import validate_config
from hrc_lab.env.clutter.rule import blockers, type_solution
from hrc_lab.env.clutter.spec import PART_TYPES
from hrc_lab.experiments.ch6_grasp import TEST, TRAIN, scene_set
from hrc_lab.grasp.graph import pair_geometry
from hrc_lab.grasp.observation import height_grids
from hrc_lab.run_naming import CONF_DIR

DEPTH_GRID = 4


def part_rows(spec, scenes):
    """Per part: depth features, graspable (the rule's), type."""
    features, labels, types = [], [], []
    for scene in scenes:
        features.append(height_grids(spec, scene.depth, scene.boxes, DEPTH_GRID).numpy())
        labels += [not b for b in blockers(spec, scene)]
        types += list(scene.types)
    return np.vstack(features), np.array(labels), np.array(types)


def pair_rows(spec, scenes, with_depth: bool):
    """Per ordered pair (j, i): geometry, one-hot types (and depth features), whether j blocks i; and its index."""
    rows, labels, index = [], [], []
    for k, scene in enumerate(scenes):
        n, found = len(scene.objects), blockers(spec, scene)
        depth = height_grids(spec, scene.depth, scene.boxes, DEPTH_GRID).numpy()
        one_hot = np.array([[t == u for u in PART_TYPES] for t in scene.types], dtype=float)
        geometry = pair_geometry(scene.boxes, scene.image.shape[0])
        source, target = np.nonzero(~np.eye(n, dtype=bool))
        for e, (j, i) in enumerate(zip(source, target)):
            parts = [geometry[e], one_hot[i], one_hot[j]] + ([depth[i], depth[j]] if with_depth else [])
            rows.append(np.concatenate(parts))
            labels.append(j in found[i])
            index.append((k, int(i), int(j)))
    return np.array(rows), np.array(labels), index


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("config", overrides=["experiment=ch6/table_6_1"])
    validated = validate_config(cfg)
    spec, protocol = validated.env, validated.protocol
    ctx = SimpleNamespace(cfg=SimpleNamespace(protocol=protocol, paths=cfg.paths))
    train = scene_set(ctx, spec, TRAIN, protocol.train_images)
    test = scene_set(ctx, spec, TEST, protocol.test_images)

    x, y, _ = part_rows(spec, train)
    x_test, y_test, types = part_rows(spec, test)
    right = GradientBoostingClassifier(random_state=0).fit(x, y).predict(x_test) == y_test
    per_type = ", ".join(f"{t} {right[types == t].mean():.2f}" for t in sorted(set(types)))
    print(f"per part, depth features: graspability {right.mean():.2f} ({per_type})")

    for with_depth in (False, True):
        x, y, _ = pair_rows(spec, train, with_depth)
        x_test, _, index = pair_rows(spec, test, with_depth)
        blocks = GradientBoostingClassifier(n_estimators=300, max_depth=4, random_state=0).fit(x, y).predict(x_test)
        predicted = {}
        for (k, i, j), b in zip(index, blocks):
            predicted.setdefault((k, i), [])
            if b:
                predicted[(k, i)].append(j)
        grasp_right, solution_right, kinds = [], [], []
        for k, scene in enumerate(test):
            for i, found in enumerate(blockers(spec, scene)):
                guess = predicted.get((k, i), [])
                grasp_right.append((not guess) == (not found))
                kinds.append(scene.types[i])
                if found:
                    solution_right.append(type_solution(scene.types[i], [scene.types[j] for j in guess])
                                          == type_solution(scene.types[i], [scene.types[j] for j in found]))
        grasp_right, kinds = np.array(grasp_right), np.array(kinds)
        per_type = ", ".join(f"{t} {grasp_right[kinds == t].mean():.2f}" for t in sorted(set(kinds)))
        inputs = "geometry, types and depth features" if with_depth else "geometry and types"
        print(f"per pair, {inputs}: graspability {grasp_right.mean():.2f} ({per_type}); solutions of ungraspable "
              f"parts right {np.mean(solution_right):.2f}")


if __name__ == "__main__":
    main()
