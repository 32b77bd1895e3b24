"""The Ch.6 robot cell's grasps with and without the pre-grasp opening (``protocol.preshape``) and the approach yaw
chosen from the depth image (``protocol.choose_yaw``), on parts the rule finds graspable: for each of the first two
such parts of generated scenes (ground-truth boxes, so detection and the solver play no part), one pick fully open,
one pre-shaped and one pre-shaped at the chosen yaw, each from the placed scene. Prints, per way, the share of picks
that lifted the named part and the share that moved a neighbour by more than 5 mm.

    MUJOCO_GL=egl .venv/bin/python scripts/ch6_pregrasp_picks.py --scenes 25 --parts 5   # ~10 min on a free core
"""

import argparse
from dataclasses import replace

import numpy as np

from hrc_lab.env.clutter.rule import graspable
from hrc_lab.env.clutter.scenes import generate_scene
from hrc_lab.env.clutter.spec import ClutterSpec
from hrc_lab.env.robot.clutter_cell import ClutterCell
from hrc_lab.grasp.robot_grasping import DISTURBED

FIRST_SEED = 777_000  # scene seeds outside the Ch.6 protocols' streams


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=25)
    parser.add_argument("--parts", type=int, default=5, help="parts per scene")
    args = parser.parse_args()
    spec = replace(ClutterSpec(), min_objects=args.parts, max_objects=args.parts)
    cell = ClutterCell(spec, seed=0)
    picks = {"fully open": [], "pre-shaped": [], "pre-shaped, yaw chosen": []}
    for seed in range(FIRST_SEED, FIRST_SEED + args.scenes):
        scene = generate_scene(spec, seed)
        parts = [i for i, ok in enumerate(graspable(spec, scene)) if ok][:2]
        for part in parts:
            for opening in picks:
                cell.place_scene(scene, spec)
                now, shown = cell.current_scene(scene.seed)
                if part not in shown:
                    continue
                box = now.boxes[shown.index(part)]
                before = cell.part_poses()[0].copy()
                if opening == "pre-shaped, yaw chosen":
                    yaw, half = cell.grasp_yaw(box, now.depth)
                else:
                    yaw, half = 0.0, cell.grasp_opening(box, now.depth) if opening == "pre-shaped" else None
                outcome = cell.pick(cell.locate(box, now.depth), half, yaw)
                moved = np.linalg.norm(cell.part_poses()[0] - before, axis=1)
                others = [j for j in range(len(moved)) if j not in (part, outcome.held)]
                picks[opening].append((outcome.held == part, any(moved[j] > DISTURBED for j in others)))
    for opening, rows in picks.items():
        lifted, disturbed = np.mean(rows, axis=0) if rows else (float("nan"), float("nan"))
        print(f"{opening}: {len(rows)} picks, lifted the named part {lifted:.2f}, moved a neighbour {disturbed:.2f}")


if __name__ == "__main__":
    main()
