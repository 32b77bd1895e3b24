"""A killed or bad run never looks successful: checks on the user's values in every group, signals -> KILLED with
exit 143/130, stale RUNNING runs, checkpoints that resume to the same result, run identity by variant."""

from __future__ import annotations

import contextlib
import http.server
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch
from mlflow.entities import Param
from mlflow.tracking import MlflowClient
from omegaconf import OmegaConf
from torch.utils.data import TensorDataset

from hrc_lab.cli import check_resumable, interrupted_message
from hrc_lab.config import LoggerConfig, TrainerConfig, validate_config
from hrc_lab.interrupts import RunInterrupted, signals_raise
from hrc_lab.kernels import cpu_kernels
from hrc_lab.registry import ConfigError
from hrc_lab.run_naming import run_name, variant_of
from hrc_lab.runs_cli import resumable, stale
from hrc_lab.tracking import RunTracker, process_identity
from hrc_lab.training import FixedStepDataModule, RandomState, RunCheckpoint, SupervisedModule, Trainer


@pytest.mark.parametrize(
    "experiment, override, key",
    [
        ("ch4/table_4_1", "trainer.max_epochs=0", "trainer.max_epochs"),
        ("ch4/table_4_1", "trainer.max_epochs=-1", "trainer.max_epochs"),
        ("ch4/table_4_1", "trainer.max_steps=0", "trainer.max_steps"),
        ("ch4/table_4_1", "trainer.checkpoint_every_n_epochs=0", "trainer.checkpoint_every_n_epochs"),
        ("ch4/table_4_1", "num_threads=0", "num_threads"),
        ("ch4/table_4_1", "resume_from=last", "resume_from"),
        ("ch4/table_4_1", "env.n_selected=0", "env.n_selected"),
        ("ch4/table_4_1", "reasoning.hidden=0", "reasoning.hidden"),
        ("ch4/table_4_1", "reasoning=gnn reasoning.layers=0", "reasoning.layers"),
        ("ch4/table_4_1", "reasoning=rf reasoning.max_depth=0", "reasoning.max_depth"),
        ("ch5/fig_5_7", "reasoning.word_dim=0", "reasoning.word_dim"),
        ("ch4/table_4_2", "motion.ndp.mode=jump", "motion.ndp.mode"),
        ("ch4/table_4_2", "motion.kind=svm", "motion.kind"),
        ("ch4/table_4_2", "motion=gpr motion.gpr_kernel=matern", "motion.gpr_kernel"),
        ("ch5/fig_5_6", "perception.batch_size=0", "perception.batch_size"),
        ("ch6/table_6_1", "grasp.lr=-1", "grasp.lr"),
        ("ch6/table_6_2_robot", "protocol.max_grasps=0", "protocol.max_grasps"),
        ("ch6/table_6_2_robot", "protocol.yaw_order=widest", "protocol.yaw_order"),
        ("ch6/table_6_2_robot", "protocol.object_counts=[7]", "protocol.object_counts"),
        ("ch4/table_4_1", "protocol.min_demos=2", "protocol.min_demos"),
        ("ch4/table_4_1", "logger.tracking_uri=nowhere", "logger.tracking_uri"),
    ],
)
def test_every_group_checks_the_users_values(compose_config, experiment, override, key):
    """Each group's schema checks run on the merged values (the trainer's once ran on its defaults only)."""
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(compose_config(f"experiment={experiment}", *override.split()))


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_marks_the_run_killed(tmp_path, signum, code):
    logger = LoggerConfig(tracking_uri=f"sqlite:///{tmp_path}/mlflow.db", artifact_root=str(tmp_path / "art"))
    # what the handlers were before (SIGINT is ignored, not Python's default, in a process started in the background)
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)}
    with pytest.raises(RunInterrupted) as caught:
        with signals_raise(), RunTracker(logger, "exp", "job", {"seed": "0"}) as tracker:
            os.kill(os.getpid(), signum)
            time.sleep(5)  # the handler raises before this ends
    assert caught.value.exit_code == code
    run = MlflowClient(tracker.tracking_uri).get_run(tracker.run_id)
    assert run.info.status == "KILLED"
    assert f"resume_from={tracker.run_id}" in interrupted_message(caught.value)
    assert run.data.tags["signal"] == signal.Signals(signum).name
    assert run.data.tags["pid"] == str(os.getpid()) and run.data.tags["host"]
    assert {s: signal.getsignal(s) for s in before} == before  # handlers restored


def test_a_job_interrupted_before_its_run_started_says_there_is_nothing_to_resume():
    """A sweep stopped while a job still composed or imported left no MLflow run; its message offered one."""
    with pytest.raises(RunInterrupted) as caught, signals_raise():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
    assert caught.value.killed_run_id is None
    message = interrupted_message(caught.value)
    assert message == "interrupted by SIGTERM before its MLflow run started; nothing to resume"


def test_an_interrupted_job_ends_its_launcher_worker():
    """A joblib (loky) worker whose job was interrupted ends with the signal's code instead of waiting for tasks from
    a parent the same signal ended (hydra/launcher=joblib's workers outlived a SIGTERM'd sweep); in the main process
    (one job, or a sequential launcher) the job exits with the code as before."""
    import pickle

    from joblib import Parallel, delayed
    from joblib.externals.loky.process_executor import TerminatedWorkerError

    from hrc_lab.interrupts import exit_interrupted

    interrupted = RunInterrupted(signal.SIGTERM)
    interrupted.killed_run_id = "abc123"
    unpickled = pickle.loads(pickle.dumps(interrupted))
    assert (unpickled.exit_code, unpickled.killed_run_id) == (143, "abc123")
    with pytest.raises(TerminatedWorkerError, match=r"EXIT\(143\)"):
        Parallel(n_jobs=2, backend="loky")(delayed(exit_interrupted)(interrupted) for _ in range(2))
    with pytest.raises(SystemExit) as caught:
        exit_interrupted(RunInterrupted(signal.SIGINT))
    assert caught.value.code == 130


def test_an_exception_marks_the_run_failed(tmp_path):
    logger = LoggerConfig(tracking_uri=f"sqlite:///{tmp_path}/mlflow.db", artifact_root=str(tmp_path / "art"))
    with pytest.raises(RuntimeError), RunTracker(logger, "exp", "job", {}) as tracker:
        raise RuntimeError("boom")
    run = MlflowClient(tracker.tracking_uri).get_run(tracker.run_id)
    assert run.info.status == "FAILED"
    assert run.data.tags["cpu"] and int(run.data.tags["cpu_cores"]) >= 1  # what its wall times depend on
    assert run.data.tags["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert run.data.tags["cpu_kernels"] == cpu_kernels()  # the kernel settings in force (hrc_lab.kernels)


def test_stale_marks_runs_whose_process_is_gone(tmp_path):
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    client = MlflowClient(uri)
    experiment = client.create_experiment("exp", artifact_location=(tmp_path / "art").as_uri())
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dead = client.create_run(experiment, tags=process_identity(gone.pid)).info.run_id
    reused = client.create_run(experiment, tags={**process_identity(), "process_start": "other-boot:1"}).info.run_id
    alive = client.create_run(experiment, tags=process_identity()).info.run_id
    elsewhere = client.create_run(experiment, tags={"host": "another-node", "pid": "1"}).info.run_id

    assert {run_id for run_id, _ in stale(uri, dry_run=True, other_hosts_hours=None)} == {dead, reused}
    assert client.get_run(dead).info.status == "RUNNING"  # a dry run changes nothing

    found = dict(stale(uri, dry_run=False, other_hosts_hours=None))
    assert "is gone" in found[dead] and "another process" in found[reused]
    assert client.get_run(dead).info.status == "KILLED"
    assert client.get_run(reused).info.status == "KILLED"
    assert client.get_run(alive).info.status == "RUNNING"
    assert client.get_run(elsewhere).info.status == "RUNNING"
    assert elsewhere in dict(stale(uri, dry_run=False, other_hosts_hours=0.0))


def test_console_scripts_read_the_store_under_hrc_lab_runs(tmp_path, monkeypatch):
    """hrc-lab-runs and hrc-lab-report default to the store jobs log to: ``$HRC_LAB_RUNS/mlflow.db`` (issue 49: the
    runs tool made an empty ./runs/mlflow.db instead)."""
    from hrc_lab import runs_cli
    from hrc_lab.report import build as report_build
    from hrc_lab.report import cli as report_cli

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HRC_LAB_RUNS", str(tmp_path / "elsewhere"))
    client = MlflowClient(f"sqlite:///{tmp_path}/elsewhere/mlflow.db")
    experiment = client.create_experiment("exp", artifact_location=(tmp_path / "art").as_uri())
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dead = client.create_run(experiment, tags=process_identity(gone.pid)).info.run_id

    runs_cli.main(["stale"])
    assert client.get_run(dead).info.status == "KILLED"
    assert not (tmp_path / "runs").exists()
    other = f"sqlite:///{tmp_path}/other/mlflow.db"  # the option where a user types it: after the subcommand
    experiment = MlflowClient(other).create_experiment("exp", artifact_location=(tmp_path / "art2").as_uri())
    dead = MlflowClient(other).create_run(experiment, tags=process_identity(gone.pid)).info.run_id
    runs_cli.main(["stale", "--tracking-uri", other])
    assert MlflowClient(other).get_run(dead).info.status == "KILLED"
    seen = {}

    def build_topic(topic, uri, *args, **kwargs):
        seen["uri"] = uri
        (tmp_path / "report.md").write_text("")
        return tmp_path / "report.md"

    monkeypatch.setattr(report_build, "build_topic", build_topic)
    report_cli.main(["ch3_rl"])
    assert seen["uri"] == f"sqlite:///{tmp_path}/elsewhere/mlflow.db"


def _fit(checkpoints: Path, max_epochs: int, resume: Path | None = None, own_generator: bool = False) -> torch.Tensor:
    """A small network with dropout, trained from a fixed seed; returns its final weights. ``own_generator``: the
    batches come from a seeded generator of the data's (as the Ch.6 detector's), not from torch's global one."""
    pl.seed_everything(0, verbose=False)
    network = torch.nn.Sequential(torch.nn.Linear(3, 16), torch.nn.Dropout(0.3), torch.nn.Linear(16, 1))
    data = [torch.randn(64, 3), torch.randn(64, 1)]
    module = SupervisedModule(network, lambda net, batch: (((net(batch[0]) - batch[1]) ** 2).mean(), {}), lr=1e-2)
    uploaded = []
    callbacks = [RandomState(), RunCheckpoint(checkpoints, 1, uploaded.append)]
    trainer = Trainer(max_epochs=max_epochs, logger=False, callbacks=callbacks, enable_progress_bar=False,
                      enable_model_summary=False, deterministic=True, resume_checkpoint=resume)
    generator = torch.Generator().manual_seed(7) if own_generator else None
    trainer.fit(module, datamodule=FixedStepDataModule(TensorDataset(*data), 8, 5, generator=generator))
    assert uploaded and uploaded[-1].name == "last.ckpt"
    return torch.cat([p.detach().flatten() for p in network.parameters()])


@pytest.mark.parametrize("own_generator", [False, True])
def test_a_resumed_fit_ends_where_an_uninterrupted_one_does(tmp_path, own_generator):
    """Stop after 2 of 5 epochs, resume from its checkpoint: same weights as 5 epochs straight (the checkpoint
    carries the generators' states, so the resumed epochs draw the same batches and dropout masks)."""
    straight = _fit(tmp_path / "straight", 5, own_generator=own_generator)
    _fit(tmp_path / "interrupted", 2, own_generator=own_generator)
    resumed = _fit(tmp_path / "resumed", 5, resume=tmp_path / "interrupted" / "last.ckpt", own_generator=own_generator)
    assert torch.equal(straight, resumed)
    assert not torch.equal(straight, _fit(tmp_path / "short", 2, own_generator=own_generator))


def test_a_resumed_run_killed_before_its_first_checkpoint_resumes_from_the_one_it_continued(tmp_path):
    """Run 1 saves a checkpoint at epoch 5 and is killed at 6; run 2 resumes it and is killed at 6, before its own
    first checkpoint. Resuming run 2 loads run 1's checkpoint (not a fresh start) and copies the curve up to it,
    values and timestamps as first logged. A resumed run that copied nothing (as before copies existed) still
    gets its ancestors' curve, each step from the nearest run that logged it."""
    logger = LoggerConfig(tracking_uri=f"sqlite:///{tmp_path}/mlflow.db", artifact_root=str(tmp_path / "art"))
    (tmp_path / "agent").mkdir()
    (tmp_path / "agent" / "agent.zip").write_text("epoch 5")
    with pytest.raises(RunInterrupted), RunTracker(logger, "exp", "first", {}) as first:
        for epoch in range(1, 7):
            first.log_metrics({"epoch_s": float(epoch)}, step=epoch)
        first.log_artifact(tmp_path / "agent", "agent")
        raise RunInterrupted(signal.SIGTERM)
    with pytest.raises(RunInterrupted), RunTracker(logger, "exp", "second", {}, parent_run_id=first.run_id) as second:
        assert second.resume_checkpoint("agent/agent.zip").read_text() == "epoch 5"
        second.log_metrics({"epoch_s": 60.0}, step=6)  # no copy: the chain still holds the curve
        raise RunInterrupted(signal.SIGTERM)
    with RunTracker(logger, "exp", "third", {}, parent_run_id=second.run_id) as third:
        assert third.resume_checkpoint("agent/agent.zip").read_text() == "epoch 5"
        assert third.resume_checkpoint("agent/missing.zip") is None
        third.copy_history(5)
    client = MlflowClient(third.tracking_uri)
    curve = sorted((m.step, m.value, m.timestamp) for m in client.get_metric_history(third.run_id, "epoch_s"))
    assert curve == sorted((m.step, m.value, m.timestamp) for m in client.get_metric_history(first.run_id, "epoch_s")
                           if m.step <= 5)
    with RunTracker(logger, "exp", "fourth", {}, parent_run_id=second.run_id) as fourth:
        fourth.copy_history(6)  # had run 2 saved a checkpoint at 6: its step 6, run 1's steps 1-5
    values = sorted((m.step, m.value) for m in client.get_metric_history(fourth.run_id, "epoch_s"))
    assert values == [(epoch, float(epoch)) for epoch in range(1, 6)] + [(6, 60.0)]


def test_variant_names_overrides_beyond_the_sweep_keys():
    sweep_keys = ["env", "reasoning", "seed"]
    assert variant_of(["experiment=ch4/table_4_1", "env=package_to_order_4of5", "seed=0"], sweep_keys) == (
        "default", [])
    assert variant_of(["logger.tracking_uri=http://x:5000", "num_threads=2", "resume_from=ab"], sweep_keys)[0] == (
        "default")
    variant, extra = variant_of(["seed=0", "trainer.max_epochs=40"], sweep_keys)
    assert variant.startswith("v") and len(variant) == 9 and extra == ["trainer.max_epochs=40"]
    assert variant != variant_of(["seed=0", "trainer.max_epochs=80"], sweep_keys)[0]
    assert variant == variant_of(["trainer.max_epochs=40", "seed=1"], sweep_keys)[0]  # order-free, seed-free


def test_run_names_differ_by_variant(compose_config):
    cfg = compose_config("experiment=ch4/table_4_1")
    assert run_name(cfg, "5of6") == "ch4/table_4_1-ours-5of6-seed0"
    assert run_name(cfg, "5of6", "v1234abcd") == "ch4/table_4_1-ours-5of6-seed0-v1234abcd"


def test_resume_from_is_checked_before_work(compose_config, tmp_path):
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    overrides = ["experiment=ch4/table_4_1", f"logger.tracking_uri={uri}", f"logger.artifact_root={tmp_path}/art"]
    parent_cfg = compose_config(*overrides)
    validated = validate_config(parent_cfg)
    tags = {"experiment": "ch4/table_4_1"}
    with pytest.raises(RunInterrupted), RunTracker(validated.logger, "ch4/table_4_1", "job", tags) as parent:
        parent.log_config(parent_cfg)
        raise RunInterrupted(signal.SIGTERM)

    same = compose_config(*overrides, f"resume_from={parent.run_id}")
    check_resumable(validate_config(same), same)  # a KILLED run of the same config: fine

    elsewhere = [f"logger.tracking_uri={uri}", f"logger.artifact_root={tmp_path}/moved", f"paths.runs_dir={tmp_path}"]
    moved = compose_config("experiment=ch4/table_4_1", *elsewhere, f"resume_from={parent.run_id}")
    check_resumable(validate_config(moved), moved)  # where runs log and write is not the job

    other = compose_config(*overrides, f"resume_from={parent.run_id}", "trainer.max_epochs=3")
    with pytest.raises(ConfigError, match=r"resume_from: .*trainer\.max_epochs"):
        check_resumable(validate_config(other), other)
    # a key added since the parent ran (absent from its params) is compared as its schema default (what the parent ran
    # with): a config at that default resumes, one that sets it otherwise does not; a key it had that is gone is
    for retired, resumes in (({}, True), ({"retired_knob": 1}, False)):
        older = OmegaConf.create(OmegaConf.to_container(compose_config(*overrides), resolve=True))  # unstructured
        del older.trainer["max_epochs"]
        older.trainer.update(retired)
        with pytest.raises(RunInterrupted), RunTracker(validated.logger, "ch4/table_4_1", "job", tags) as run:
            run.log_config(older)
            raise RunInterrupted(signal.SIGTERM)
        today = compose_config(*overrides, f"resume_from={run.run_id}")
        if resumes:
            check_resumable(validate_config(today), today)
            default = OmegaConf.structured(TrainerConfig).max_epochs
            away = compose_config(*overrides, f"resume_from={run.run_id}", f"trainer.max_epochs={default + 1}")
            with pytest.raises(ConfigError, match=rf"trainer\.max_epochs='{default}' there, '{default + 1}' here"):
                check_resumable(validate_config(away), away)
        else:
            with pytest.raises(ConfigError, match=r"trainer\.retired_knob='1' there, None here"):
                check_resumable(validate_config(today), today)
    unknown = compose_config(*overrides, f"resume_from={'0' * 32}")
    with pytest.raises(ConfigError, match="resume_from: no MLflow run"):
        check_resumable(validate_config(unknown), unknown)


def test_resumable_lists_the_killed_jobs_left_with_their_commands(compose_config, tmp_path, capsys):
    """Listed: a KILLED run nothing resumed or replaced, with the command that resumes it, also when a FINISHED run
    sets a key added since it ran away from that key's default. Not listed: a killed run a later run resumed, one
    whose config a FINISHED run did (keys added since, at their defaults, aside), one today's config cannot
    resume (its logged config is not what its overrides compose to now: the reason is printed), an invalidated
    one and one whose job a RUNNING run does now."""
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    base = ["experiment=ch4/table_4_1", f"logger.tracking_uri={uri}", f"logger.artifact_root={tmp_path}/art"]

    def job(overrides: list[str], ending: str, logged: list[str] | None = None, parent: str | None = None,
            added_since: str | None = None) -> str:
        cfg = compose_config(*(logged if logged is not None else overrides))
        if added_since:  # a trainer key the run's code did not have yet
            cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
            del cfg.trainer[added_since]
        tracker = RunTracker(validate_config(cfg).logger, "ch4/table_4_1", "job", {"experiment": "ch4/table_4_1"},
                             parent_run_id=parent)
        with contextlib.suppress(RunInterrupted), tracker:
            tracker.log_config(cfg)
            tracker.log_text("\n".join(f"- {o}" for o in overrides), "hydra/overrides.yaml")
            if ending == "KILLED":
                raise RunInterrupted(signal.SIGTERM)
        return tracker.run_id

    left = job([*base, "seed=1"], "KILLED")
    resumed = job([*base, "seed=2"], "KILLED")
    killed_again = job([*base, "seed=2", f"resume_from={resumed}"], "KILLED", parent=resumed)
    job([*base, "seed=3"], "KILLED")
    job([*base, "seed=3"], "FINISHED")
    stale_config = job([*base, "seed=4"], "KILLED", logged=[*base, "seed=4", "trainer.max_epochs=3"])
    invalid = job([*base, "seed=5"], "KILLED")
    job([*base, "seed=6"], "KILLED", added_since="max_epochs")  # done since by a run that logs one key more
    job([*base, "seed=6"], "FINISHED")
    # not done by a run that sets that key away from the default the killed run ran with
    other_job = job([*base, "seed=8"], "KILLED", added_since="max_epochs")
    job([*base, "seed=8", "trainer.max_epochs=3"], "FINISHED")
    MlflowClient(uri).set_tag(invalid, "invalidated", "a bug, fixed since")
    restarted = job([*base, "seed=7"], "KILLED")  # its job started afresh, running now
    client = MlflowClient(uri)
    twin = client.create_run(client.get_run(restarted).info.experiment_id, tags={"experiment": "ch4/table_4_1"})
    client.log_batch(twin.info.run_id, params=[Param(k, v) for k, v in client.get_run(restarted).data.params.items()])

    found = dict(resumable(uri))
    assert set(found) == {left, killed_again, other_job}
    assert found[left] == " ".join(["hrc-lab", "hydra.mode=RUN", *base, "seed=1", f"resume_from={left}"])
    assert found[killed_again].endswith(f"seed=2 resume_from={killed_again}")
    printed = capsys.readouterr().out
    assert f"cannot resume today (resume_from: run {stale_config} had another config: trainer.max_epochs" in printed
    assert "job: invalidated (a bug, fixed since)" in printed  # and not in found, above
    assert f"job: its job is running now (run {twin.info.run_id};" in printed
    again = compose_config(*base, "seed=5", f"resume_from={invalid}")
    with pytest.raises(ConfigError, match=r"is invalidated \(a bug, fixed since\); start the job afresh"):
        check_resumable(validate_config(again), again)


TINY_JOB = ["experiment=ch4/table_4_1", "hydra.mode=RUN", "env=package_to_order_2of3", "reasoning=ours", "seed=0",
            "protocol.min_demos=20", "trainer.max_epochs=30"]


def _runs(uri: str) -> list:
    client = MlflowClient(uri)
    return client.search_runs([e.experiment_id for e in client.search_experiments()],
                              order_by=["attributes.start_time ASC"])


@pytest.mark.slow
def test_kill_then_resume_gives_the_uninterrupted_result(tmp_path, console_script):
    """SIGTERM mid-training: exit 143 and a KILLED run; resume_from continues from its checkpoint into a new
    FINISHED run tagged with its parent, with the final metrics of an uninterrupted run of the same seed."""
    runs = tmp_path / "runs"
    env = dict(os.environ, HRC_LAB_RUNS=str(runs), PYTHONWARNINGS="ignore")
    uri = f"sqlite:///{runs}/mlflow.db"
    job = subprocess.Popen([console_script("hrc-lab"), *TINY_JOB], env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not list(runs.glob("hydra/ch4/table_4_1/*/checkpoints/model/last.ckpt")):
        assert job.poll() is None and time.monotonic() < deadline, "no checkpoint before the job ended"
        time.sleep(0.2)
    time.sleep(2)
    job.send_signal(signal.SIGTERM)
    _, stderr = job.communicate(timeout=120)
    assert job.returncode == 143, stderr[-2000:]
    (killed,) = _runs(uri)
    assert killed.info.status == "KILLED" and killed.data.tags["signal"] == "SIGTERM"
    killed_epochs = killed.data.metrics["epoch"]
    assert killed_epochs < 29

    for extra in ([f"resume_from={killed.info.run_id}"], []):
        result = subprocess.run([console_script("hrc-lab"), *TINY_JOB, *extra], env=env, capture_output=True,
                                text=True, timeout=300)
        assert result.returncode == 0, result.stderr[-2000:]
    _, resumed, straight = _runs(uri)
    assert resumed.info.status == straight.info.status == "FINISHED"
    assert resumed.data.tags["resumed_from"] == killed.info.run_id
    epochs = [m.value for m in MlflowClient(uri).get_metric_history(resumed.info.run_id, "epoch")]
    assert epochs[0] > 0, "the resumed run trained from scratch"
    for metric in ("train_loss", "sr", "acc_o", "acc_g"):
        assert resumed.data.metrics[metric] == straight.data.metrics[metric], metric


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["experiment=ch4/fig_4_9", "reasoning=gnn"], r"reasoning: protocol ch4_fig_4_9 runs with reasoning=ours"),
        (["experiment=ch6/table_6_1", "env=package_to_order"], r"env: protocol ch6_table_6_1 runs with env=clutter"),
        (["experiment=ch3/table_3_1", "reasoning=ours"], r"reasoning: .* runs with reasoning=none"),
        (["experiment=ch5/fig_5_6", "perception.window=30"], r"perception\.window=30 must equal env\.video\.window"),
        (["experiment=ch6/table_6_1", "env.image_size=192", "grasp.detector.image_size=160"],
         r"grasp\.detector\.image_size=160 must equal env\.image_size=192"),
        (["experiment=ch4/practical", "protocol.max_missing=5"], r"protocol\.max_missing=5 must be < env\.n_objects"),
    ],
)
def test_a_wrong_combination_fails_before_work(compose_config, overrides, message):
    """A protocol declares the env and modules it runs with; settings shared by two groups are checked together."""
    with pytest.raises(ConfigError, match=message):
        validate_config(compose_config(*overrides))


def test_shared_facts_are_interpolations(compose_config):
    """The detector's input size and the action window follow the env unless a user sets them apart."""
    grasp = validate_config(compose_config("experiment=ch6/table_6_1", "env.image_size=192",
                                           "grasp.detector.image_size=192"))
    assert grasp.grasp.detector.image_size == 192
    perception = validate_config(compose_config("experiment=ch5/fig_5_6", "env.video.window=30"))
    assert perception.perception.window == 30


def test_jobs_and_sweeps_started_in_the_same_second_get_their_own_folders(compose_config):
    """Two jobs or two one-job sweeps launched together (one per core) must not write each other's checkpoints and
    .hydra files: their output folders differ below the second."""
    def folders() -> tuple[Path, Path]:
        hydra_cfg = compose_config("experiment=ch4/table_4_1", return_hydra_config=True).hydra
        return Path(hydra_cfg.run.dir), Path(hydra_cfg.sweep.dir)

    (run_a, sweep_a), (run_b, sweep_b) = folders(), folders()  # well within one second
    assert run_a != run_b and run_a.parent == run_b.parent
    assert sweep_a != sweep_b and sweep_a.parent == sweep_b.parent


def test_a_users_own_config_file_makes_a_variant(compose_config, tmp_path):
    from hydra.core.hydra_config import HydraConfig

    from hrc_lab.run_naming import job_tags

    def tags(*overrides: str) -> dict[str, str]:
        cfg = compose_config("experiment=ch4/table_4_1", *overrides, return_hydra_config=True)
        HydraConfig.instance().set_config(cfg)
        try:
            return job_tags()
        finally:
            HydraConfig.instance().cfg = None

    # the user's folder is searched after conf/ (as `--config-dir <dir>` is); env/my_cell.yaml exists only there
    users_dir = f"hydra.searchpath=[file://{tmp_path}]"
    (tmp_path / "env").mkdir()
    cell = tmp_path / "env" / "my_cell.yaml"
    cell.write_text("defaults:\n  - package_to_order_4of5\n  - _self_\n\nn_objects: 6\n")
    mine = tags(users_dir, "env=my_cell")  # env is a sweep key of the experiment: only the file makes the variant
    assert mine["variant"] != "default"
    assert mine["variant_overrides"].startswith(f"hydra.searchpath {tmp_path} (env/my_cell.yaml@")
    assert tags(users_dir, "env=my_cell", "seed=3")["variant"] == mine["variant"]
    cell.write_text(cell.read_text().replace("n_objects: 6", "n_objects: 7"))
    assert tags(users_dir, "env=my_cell")["variant"] not in ("default", mine["variant"])
    # the same folder, but every file composed is the repository's: the default protocol
    (tmp_path / "env" / "package_to_order_4of5.yaml").write_text("defaults:\n  - package_to_order\n\nn_objects: 9\n")
    assert tags(users_dir, "env=package_to_order_4of5")["variant"] == "default"


class _DeadDatabase(http.server.BaseHTTPRequestHandler):
    """An MLflow server whose database is gone: /health answers, every API call is a 503."""

    def do_GET(self):  # noqa: N802 (http.server's name)
        self._answer(200 if self.path == "/health" else 503)

    def do_POST(self):  # noqa: N802
        self._answer(503)

    def _answer(self, code: int) -> None:
        self.send_response(code)
        self.send_header("Content-Type", "text/plain")
        self.end_headers()
        self.wfile.write(b"OK" if code == 200 else b"database unavailable")

    def log_message(self, *args) -> None:
        pass


@pytest.fixture
def dead_database_server():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _DeadDatabase)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()


def test_a_job_gives_up_on_a_dead_tracking_server_within_30_s_naming_it(dead_database_server, tmp_path, monkeypatch):
    """Issue 49: with the server's database killed, jobs failed after 282-534 s of retries with MLflow's traceback."""
    from hrc_lab.server import database_answers, healthy
    from hrc_lab.tracking import SERVER_REQUEST_ENV, TrackingUnavailable

    for key in SERVER_REQUEST_ENV:  # the defaults apply (and are undone after the test)
        monkeypatch.setenv(key, "")
        monkeypatch.delenv(key)
    start = time.monotonic()
    with pytest.raises(TrackingUnavailable, match=re.escape(dead_database_server)) as raised:
        RunTracker(LoggerConfig(tracking_uri=dead_database_server, artifact_root=str(tmp_path)), "exp", "run", {})
    assert time.monotonic() - start < 30
    assert "hrc-lab-server status" in str(raised.value) and "hrc-lab-runs stale" in str(raised.value)
    # what `hrc-lab-server status` reads: the process answers, its database does not
    assert healthy(dead_database_server) and not database_answers(dead_database_server)


def test_server_status_fails_when_its_database_does_not_answer(dead_database_server, tmp_path):
    """``hrc-lab-server status`` exits non-zero when MLflow's process answers but its database does not."""
    import json

    from hrc_lab.processes import process_start
    from hrc_lab.server import main, state_file, status

    state = {"tracking_uri": dead_database_server, "mlflow_pid": os.getpid(),
             "mlflow_start": process_start(os.getpid()), "db_uri": "postgresql+psycopg://postgres@127.0.0.1:1/mlflow"}
    state_file(tmp_path).write_text(json.dumps(state))
    running, text = status(tmp_path)
    assert not running and "database does not answer" in text and "hrc-lab-server start" in text
    assert main(["status", "--dir", str(tmp_path)]) == 3
