"""The Ch.6 robot cell's grasps with and without the pre-grasp opening (``protocol.preshape``), the approach yaw
chosen from the depth image (``protocol.choose_yaw``) and the finger tips' depth below the part's top
(``protocol.grip_depth``, against the rule's ``env.grasp_depth``), on parts the rule finds graspable: for each of the
first two such parts of generated scenes (ground-truth boxes, so detection and the solver play no part), one pick
per way, each from the placed scene. Prints, per way, the share of picks that lifted the named part and the share
that moved a neighbour by more than 5 mm.

    MUJOCO_GL=egl .venv/bin/python scripts/ch6_pregrasp_picks.py --scenes 25 --parts 5   # ~13 min on a free core
"""

import argparse
from dataclasses import replace

import numpy as np

from hrc_lab.env.clutter.rule import graspable
from hrc_lab.env.clutter.scenes import generate_scene
from hrc_lab.env.clutter.spec import ClutterSpec
from hrc_lab.env.robot.clutter_cell import ClutterCell
from hrc_lab.experiments.schemas import Table62RobotProtocol
from hrc_lab.grasp.robot_grasping import DISTURBED

FIRST_SEED = 777_000  # scene seeds outside the Ch.6 protocols' streams


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=25)
    parser.add_argument("--parts", type=int, default=5, help="parts per scene")
    args = parser.parse_args()
    spec = replace(ClutterSpec(), min_objects=args.parts, max_objects=args.parts)
    cell = ClutterCell(spec, seed=0)
    robot_row = Table62RobotProtocol()
    ways = {  # name: (preshape, choose the yaw, grip depth)
        "fully open": (False, False, spec.grasp_depth),
        "pre-shaped": (True, False, spec.grasp_depth),
        "pre-shaped, yaw chosen": (True, True, spec.grasp_depth),
        f"pre-shaped, yaw chosen, {robot_row.grip_depth * 1000:g} mm deep": (True, True, robot_row.grip_depth),
    }
    picks = {way: [] for way in ways}
    for seed in range(FIRST_SEED, FIRST_SEED + args.scenes):
        scene = generate_scene(spec, seed)
        parts = [i for i, ok in enumerate(graspable(spec, scene)) if ok][:2]
        for part in parts:
            for way, (preshape, choose_yaw, grip_depth) in ways.items():
                cell.grip_depth = grip_depth
                cell.place_scene(scene, spec)
                now, shown = cell.current_scene(scene.seed)
                if part not in shown:
                    continue
                box = now.objects[shown.index(part)].box
                before = cell.part_poses()[0].copy()
                approach = cell.approach(box, now.depth, preshape, choose_yaw, robot_row.yaw_order)
                outcome = cell.pick(cell.locate(box, now.depth), approach.half_opening, approach.yaw, approach.tips)
                moved = np.linalg.norm(cell.part_poses()[0] - before, axis=1)
                others = [j for j in range(len(moved)) if j not in (part, outcome.held)]
                picks[way].append((outcome.held == part, any(moved[j] > DISTURBED for j in others)))
    for way, rows in picks.items():
        lifted, disturbed = np.mean(rows, axis=0) if rows else (float("nan"), float("nan"))
        print(f"{way}: {len(rows)} picks, lifted the named part {lifted:.2f}, moved a neighbour {disturbed:.2f}")


if __name__ == "__main__":
    main()
