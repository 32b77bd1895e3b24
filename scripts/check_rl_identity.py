"""Bit identity of a tiny fixed-seed Fig. 3.13 job: a speed-up of the RL loop must not move its results (issue 80,
item 4).

``record`` runs one tiny ``hrc-lab experiment=ch3/fig_3_13`` job (two-object cell, so two subtasks in sequence;
lambda 0.7, so guided and unguided episodes; the guided episodes as demonstrations, behaviour-cloning start and
critic warm-up; HER, the normaliser, evaluation and the final evaluation; the experiment's 2 x 256 networks and
batch of 256, so the updates run the real job's matrix shapes) in a subprocess and writes a digest:
SHA-256 of every tensor of each subtask's final policy (actor, critic, their targets, the normaliser's statistics),
of its replay and demonstration buffers' stored rows, of the guide's networks, and every metric the run logged
(per-epoch histories included, clocks excluded). ``compare`` names what differs between two digests.

Before / after: record with the code before the change (e.g. ``git archive <commit> | tar -x -C /tmp/before`` and
``--code /tmp/before``: that tree's ``hrc_lab`` and ``conf`` are imported), then with the working tree, then compare::

    .venv/bin/python scripts/check_rl_identity.py record --code /tmp/before --out /tmp/before.json
    .venv/bin/python scripts/check_rl_identity.py record --out /tmp/after.json
    .venv/bin/python scripts/check_rl_identity.py compare /tmp/before.json /tmp/after.json

``--jobs 2`` runs the job twice in one ``paths.runs_dir`` (the second finds the first's cached guide) and checks that
both give the same digest.
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import io
import json
import os
import pickle
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OVERRIDES = [
    "experiment=ch3/fig_3_13", "hydra.mode=RUN", "env=error_correction_two_object_case1", "seed=0", "rl.lam=0.7",
    "trainer.max_epochs=1", "motion.steps=20", "motion.ndp.steps=20", "motion.classifier.steps=20",
    "protocol.demos=2", "protocol.epochs=2", "rl.cycles_per_epoch=2", "rl.episodes_per_cycle=2",
    "rl.gradient_steps=8", "protocol.eval_episodes=2", "protocol.final_eval_episodes=2", "rl.steps_per_subtask=20",
    "rl.learning_starts=40", "rl.batch_size=256", "rl.demo_batch_size=32", "rl.net_arch=[256,256]",
    "rl.buffer_size=1000", "rl.bc_pretrain_steps=5", "rl.critic_warmup_steps=4",
]
WALL_CLOCK = re.compile(r"(latency|_ms\b|_ms_|_s$|_s_|seconds|per_s|per_min|wall|time|fps)")


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def tensor_digests(state: dict) -> dict[str, str]:
    import torch

    return {key: _sha(value.detach().cpu().contiguous().numpy().tobytes()) if isinstance(value, torch.Tensor)
            else repr(value) for key, value in sorted(state.items())}


def buffer_digest(path: Path) -> dict[str, str]:
    """SHA-256 of the stored rows of each array of a pickled HER buffer (and its write position)."""
    import numpy as np

    with gzip.open(path, "rb") as file:
        buffer = pickle.load(file)
    rows = buffer.buffer_size if buffer.full else buffer.pos
    out = {"pos": str(buffer.pos), "full": str(buffer.full)}
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "ep_start", "ep_length"):
        value = getattr(buffer, name, None)
        arrays = value.items() if isinstance(value, dict) else [("", value)]
        for key, array in arrays:
            if isinstance(array, np.ndarray):
                out[f"{name}{'/' + key if key else ''}"] = _sha(np.ascontiguousarray(array[:rows]).tobytes())
    return out


def digest(runs_dir: Path, output_dir: Path) -> dict:
    """The digest of the one run in ``runs_dir`` whose Hydra output folder is ``output_dir``."""
    import torch
    from mlflow.tracking import MlflowClient

    out: dict = {"agents": {}, "guide": {}, "metrics": {}}
    for agent in sorted(output_dir.glob("agents/subtask*")):
        with zipfile.ZipFile(agent / "agent.zip") as archive:
            policy = torch.load(io.BytesIO(archive.read("policy.pth")), map_location="cpu", weights_only=True)
        entry = {"policy": tensor_digests(policy)}
        for name in ("replay_buffer.pkl.gz", "demo_buffer.pkl.gz"):
            if (agent / name).exists():
                entry[name] = buffer_digest(agent / name)
        out["agents"][agent.name] = entry
    client = MlflowClient(f"sqlite:///{runs_dir / 'mlflow.db'}")
    (run,) = [r for e in client.search_experiments() for r in client.search_runs([e.experiment_id])
              if r.data.tags.get("experiment") == "ch3/fig_3_13" and
              client.download_artifacts(r.info.run_id, "hydra/output_dir.txt") and
              Path(client.download_artifacts(r.info.run_id, "hydra/output_dir.txt")).read_text().strip()
              == str(output_dir.resolve())]
    for name in ("model/subgoal.pt", "model/ndp.pt"):
        try:
            path = client.download_artifacts(run.info.run_id, name)
        except Exception:  # noqa: BLE001 (not logged)
            continue
        out["guide"][name] = _sha(Path(path).read_bytes()) if Path(path).is_file() else sorted(
            _sha(p.read_bytes()) for p in Path(path).rglob("*") if p.is_file() and "MLmodel" not in p.name)
    for key in sorted(run.data.metrics):
        if WALL_CLOCK.search(key):
            continue
        out["metrics"][key] = [(m.step, m.value) for m in sorted(client.get_metric_history(run.info.run_id, key),
                                                                 key=lambda m: (m.step, m.timestamp))]
    return out


def run_job(code: Path, runs_dir: Path, extra: list[str]) -> Path:
    """One tiny job with ``code``'s hrc_lab and conf; its Hydra output folder."""
    env = {**os.environ, "HRC_LAB_RUNS": str(runs_dir), "PYTHONPATH": str(code)}
    before = set((runs_dir / "hydra").rglob("*/.hydra")) if (runs_dir / "hydra").exists() else set()
    subprocess.run([sys.executable, "-c", "import sys; from hrc_lab.cli import main; sys.argv[0] = 'hrc-lab'; main()",
                    *OVERRIDES, *extra], env=env, check=True, cwd=code)
    (new,) = set((runs_dir / "hydra").rglob("*/.hydra")) - before
    return new.parent


def record(args) -> None:
    code = Path(args.code).resolve()
    runs_dir = Path(args.runs_dir or tempfile.mkdtemp(prefix="rl_identity_"))
    digests = [digest(runs_dir, run_job(code, runs_dir, args.extra)) for _ in range(args.jobs)]
    for k, other in enumerate(digests[1:], start=2):
        moved = differences(digests[0], other)
        if moved:
            sys.exit(f"job {k} in the same runs_dir differs from job 1:\n  " + "\n  ".join(moved))
    result = {"code": str(code), "overrides": OVERRIDES + list(args.extra), "digest": digests[0]}
    Path(args.out).write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    print(f"{args.out}: {len(digests[0]['agents'])} agents, {len(digests[0]['metrics'])} metrics"
          + (f"; {args.jobs} jobs identical" if args.jobs > 1 else ""))


def differences(a: dict, b: dict, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        found = [f"{path}/{k}: only in the first" for k in sorted(a.keys() - b.keys())]
        found += [f"{path}/{k}: only in the second" for k in sorted(b.keys() - a.keys())]
        for key in sorted(a.keys() & b.keys()):
            found += differences(a[key], b[key], f"{path}/{key}")
        return found
    return [] if a == b else [f"{path}: {str(a)[:80]} != {str(b)[:80]}"]


def compare(args) -> None:
    a, b = (json.loads(Path(p).read_text()) for p in (args.first, args.second))
    if a["overrides"] != b["overrides"]:
        sys.exit("the two digests are of jobs with other overrides")
    moved = differences(a["digest"], b["digest"])
    if moved:
        sys.exit(f"{len(moved)} differences:\n  " + "\n  ".join(moved[:40]))
    n = sum(len(agent["policy"]) for agent in a["digest"]["agents"].values())
    print(f"identical: {len(a['digest']['agents'])} final policies ({n} tensors), their buffers, the guide's "
          f"networks and {len(a['digest']['metrics'])} metric histories")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(required=True)
    rec = sub.add_parser("record", help="run the tiny job and write its digest")
    rec.add_argument("--code", default=str(ROOT), help="a tree with hrc_lab/ and conf/ (default: this one)")
    rec.add_argument("--out", required=True)
    rec.add_argument("--runs-dir", help="paths.runs_dir of the job (default: a new temporary folder)")
    rec.add_argument("--jobs", type=int, default=1, help="run the job this many times in one runs_dir")
    rec.add_argument("extra", nargs="*", help="more hrc-lab overrides")
    rec.set_defaults(func=record)
    cmp = sub.add_parser("compare", help="name the differences of two digests")
    cmp.add_argument("first")
    cmp.add_argument("second")
    cmp.set_defaults(func=compare)
    args = parser.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
