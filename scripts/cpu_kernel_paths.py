"""Which CPU kernel paths change a trained network, measured: the Ch.6 detector trained a few steps from one seed on
the same scenes under several kernel settings, each in its own process (the libraries read them at their first
call). Rows: this CPU's widest paths (what hrc_lab ran before :mod:`hrc_lab.kernels`), the kernels an AVX2-only or
an SSE4.1-only CPU would pick (the same libraries capped at that instruction set), MKL's COMPATIBLE branch, and
hrc_lab's pinned set. Equal weight hashes mean bit-identical weights.

    MUJOCO_GL=egl .venv/bin/python scripts/cpu_kernel_paths.py --steps 8 --out reports/benchmarks/cpu_kernels.md
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from hrc_lab.kernels import PINNED, SWITCH

WIDEST = {SWITCH: "native"}  # nothing pinned: each library detects the CPU
SETTINGS = {
    "this CPU's widest paths (before hrc_lab.kernels)": WIDEST,
    "an AVX2-only CPU's paths": {**WIDEST, "ONEDNN_MAX_CPU_ISA": "AVX2", "MKL_ENABLE_INSTRUCTIONS": "AVX2",
                                 "ATEN_CPU_CAPABILITY": "avx2"},
    "an SSE4.1-only CPU's paths": {**WIDEST, "ONEDNN_MAX_CPU_ISA": "SSE41", "MKL_ENABLE_INSTRUCTIONS": "SSE4_2",
                                   "ATEN_CPU_CAPABILITY": "default"},
    "MKL's COMPATIBLE branch": {**WIDEST, "MKL_CBWR": "COMPATIBLE"},
    "hrc_lab's pinned set (hrc_lab.kernels.PINNED)": dict(PINNED),
}


def train_steps(steps: int, n_scenes: int) -> dict:
    """Fit the default detector (``ObjectDetector.fit``, the runs' own training) for ``steps`` steps of 8 scenes
    from seed 0, in this process; its mean training loss, a hash of its weights and the seconds per step."""
    import lightning.pytorch as pl
    import torch

    from hrc_lab.env.clutter.scenes import generate_scenes
    from hrc_lab.env.clutter.spec import PART_TYPES, ClutterSpec
    from hrc_lab.grasp.configs import DetectorConfig
    from hrc_lab.grasp.detector import ObjectDetector

    torch.set_num_threads(1)
    scenes = generate_scenes(ClutterSpec(), range(n_scenes), progress=False)
    detector = ObjectDetector(DetectorConfig(steps=steps), PART_TYPES)
    trainer = pl.Trainer(accelerator="cpu", max_epochs=1, logger=False, enable_checkpointing=False,
                         enable_progress_bar=False, enable_model_summary=False)
    start = time.perf_counter()
    detector.fit(scenes, trainer)
    seconds = (time.perf_counter() - start) / steps
    weights = b"".join(p.detach().numpy().tobytes() for p in detector.model.parameters())
    return {"loss": float(trainer.callback_metrics["train_loss"]), "hash": hashlib.sha1(weights).hexdigest()[:12],
            "s/step": seconds, "ATen": torch.backends.cpu.get_cpu_capability()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=8, help="training steps per setting (default 8)")
    parser.add_argument("--scenes", type=int, default=16, help="training scenes (default 16)")
    parser.add_argument("--out", type=Path, help="write the table here (markdown) as well")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.steps < 1 or args.scenes < 1:
        parser.error("--steps and --scenes must be >= 1")
    if args.child:
        print(json.dumps(train_steps(args.steps, args.scenes)))
        return
    rows = []
    for name, env in SETTINGS.items():
        child = {k: v for k, v in os.environ.items() if k not in {*PINNED, SWITCH, "MKL_ENABLE_INSTRUCTIONS"}} | env
        out = subprocess.run([sys.executable, __file__, "--child", "--steps", str(args.steps), "--scenes",
                              str(args.scenes)], env=child, check=True, capture_output=True, text=True).stdout
        result = json.loads(out.strip().splitlines()[-1])
        settings = " ".join(f"{k}={v}" for k, v in env.items())
        rows.append({"kernels": name, "settings": settings, "ATen's path": result["ATen"],
                     f"mean loss over {args.steps} steps": round(result["loss"], 6), "weights (sha1)": result["hash"],
                     "s / step": round(result["s/step"], 3)})
        print(rows[-1], flush=True)
    table = pd.DataFrame(rows).to_markdown(index=False)
    print(table)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(f"# CPU kernel paths and the Ch.6 detector's weights\n\n"
                            f"`{' '.join(['python', 'scripts/cpu_kernel_paths.py', *sys.argv[1:]])}` "
                            f"(the script's docstring says what a row is), on {platform_name()}. Equal hashes: "
                            f"bit-identical weights. Seconds per step: one thread, wall clock, beside whatever else "
                            f"the machine ran.\n\n{table}\n")


def platform_name() -> str:
    """The CPU's model name and core count, from /proc/cpuinfo where there is one."""
    try:
        names = [line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                 if line.startswith("model name")]
    except OSError:
        names = []
    return f"{names[0] if names else 'an unnamed CPU'}, {os.cpu_count()} cores"


if __name__ == "__main__":
    main()
