"""Sub-goal planners and the neural dynamic planner behind one numpy interface, with standardised inputs and
targets (statistics of the training set)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
import torch.nn.functional as F

from hrc_lab.motion.configs import ClassifierConfig, NDPConfig, SubgoalConfig
from hrc_lab.motion.networks import FullObservationActor, NeuralDynamicPlanner, TaskConditionedVI, variational_loss
from hrc_lab.training import accuracy, fit_tensors


class Standardiser:
    def __init__(self, data: np.ndarray) -> None:
        self.mean = data.mean(0)
        self.std = data.std(0) + 1e-6

    def __call__(self, data: np.ndarray) -> np.ndarray:
        return (data - self.mean) / self.std

    def inverse(self, data: np.ndarray) -> np.ndarray:
        return data * self.std + self.mean


def _tensor(array: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.asarray(array), dtype=torch.float32)


def jitter_r(x: np.ndarray, labels: np.ndarray, subgoals: np.ndarray, std: float, copies: int,
             seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs plus ``copies`` copies with Gaussian noise of ``std`` (m) on r, the last three columns of x."""
    if std == 0 or copies == 0:
        return x, labels, subgoals
    rng = np.random.default_rng(seed)
    noisy = np.repeat(x[None], copies, 0)
    noisy[..., -3:] += rng.normal(0.0, std, (copies, len(x), 3))
    return (np.vstack([x, *noisy]), np.tile(labels, copies + 1), np.tile(subgoals, (copies + 1, 1)))


class SubgoalPlanner:
    """s = f(x, l): ``fit`` on (observation, label index, sub-goal) triples, ``predict`` the sub-goal mean and std.

    ``indices`` (the sub-goal's index within its stage, < ``n_subgoals``) are used only with
    ``config.label_per_subgoal``, which turns every stage label into ``n_subgoals`` labels; ``references`` (N, 3),
    each pair's stage reference position, only with ``config.relative_targets``, which fits and predicts s minus it.
    """

    def __init__(self, config: SubgoalConfig, n_labels: int, n_subgoals: int = 1, seed: int = 0) -> None:
        self.config = config
        self.n_labels = n_labels
        self.n_subgoals = n_subgoals
        self.seed = seed

    def _onehot(self, labels: np.ndarray, indices: np.ndarray | None) -> np.ndarray:
        if not self.config.label_per_subgoal:
            return np.eye(self.n_labels)[labels]
        if indices is None:
            raise ValueError("motion.label_per_subgoal needs the sub-goal index of every pair")
        if np.any((indices < 0) | (indices >= self.n_subgoals)):
            raise ValueError(f"sub-goal indices must be in [0, {self.n_subgoals}), got {np.unique(indices)}")
        return np.eye(self.n_labels * self.n_subgoals)[labels * self.n_subgoals + indices]

    def _features(self, x: np.ndarray) -> np.ndarray:
        """x as the regressor reads it: with ``relative_to_r`` every 3-vector before r (the last three) minus r."""
        if not self.config.relative_to_r:
            return x
        if (x.shape[1] - 3) % 3:
            raise ValueError(f"motion.relative_to_r needs x = [3-vectors..., r], got {x.shape[1]} columns")
        r = x[:, -3:]
        return np.hstack([x[:, :-3] - np.tile(r, (x.shape[1] - 3) // 3), r])

    def _inputs(self, x: np.ndarray, labels: np.ndarray, indices: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        return self.x_scale(self._features(x)), self._onehot(labels, indices)

    def _origins(self, references: np.ndarray | None, n: int) -> np.ndarray:
        """What the planner's targets are relative to: the stage references with ``relative_targets``, else 0."""
        if not self.config.relative_targets:
            return np.zeros((n, 3))
        if references is None:
            raise ValueError("motion.relative_targets needs the stage reference position of every pair")
        references = np.atleast_2d(references)
        if references.shape != (n, 3):
            raise ValueError(f"stage references must have shape ({n}, 3), got {references.shape}")
        return references

    def fit(self, x: np.ndarray, labels: np.ndarray, subgoals: np.ndarray,
            trainer_factory: Callable | None = None, indices: np.ndarray | None = None,
            references: np.ndarray | None = None) -> SubgoalPlanner:
        """``x`` ends with r, the lip position (3); see ``SubgoalConfig.r_jitter_m``."""
        cfg = self.config
        n = len(x)
        subgoals = subgoals - self._origins(references, n)
        x, labels, subgoals = jitter_r(x, labels, subgoals, cfg.r_jitter_m, cfg.r_jitter_copies, self.seed)
        indices = None if indices is None else np.tile(indices, len(x) // n)
        self.x_scale, self.s_scale = Standardiser(self._features(x)), Standardiser(subgoals)
        xs, onehot = self._inputs(x, labels, indices)
        target = self.s_scale(subgoals)
        if cfg.kind == "gpr":
            from sklearn.gaussian_process import GaussianProcessRegressor
            from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

            rng = np.random.default_rng(self.seed)
            keep = rng.permutation(len(xs))[: cfg.gpr_max_points]
            features = np.hstack([xs, onehot]) if cfg.use_labels else xs
            length_scale = np.ones(features.shape[1]) if cfg.gpr_kernel == "ard" else 1.0
            kernel = ConstantKernel() * RBF(length_scale=length_scale) + WhiteKernel(1e-3)
            self.gpr = GaussianProcessRegressor(kernel, normalize_y=False, random_state=self.seed)
            self.gpr.fit(features[keep], target[keep])
            return self
        torch.manual_seed(self.seed)
        self.network = TaskConditionedVI(x.shape[1], onehot.shape[1], cfg.hidden, subgoals.shape[1], cfg.use_labels,
                                         stochastic=cfg.kind == "vi")
        if cfg.kind == "vi":
            def objective(net, batch):
                xb, lb, sb = batch
                mean, std = net(xb, lb)
                loss, nll, kl = variational_loss(mean, std, sb, cfg.likelihood_std, cfg.kl_weight)
                return loss, {"nll": nll, "kl": kl}
        else:
            def objective(net, batch):
                xb, lb, sb = batch
                mean, _ = net(xb, lb)
                return F.mse_loss(mean, sb), {}
        fit_tensors(self.network, objective, [_tensor(xs), _tensor(onehot), _tensor(target)], cfg.lr, cfg.steps,
                    cfg.batch_size, trainer_factory)
        return self

    def predict(self, x: np.ndarray, labels: np.ndarray, indices: np.ndarray | None = None,
                references: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        x = np.atleast_2d(x)
        origins = self._origins(references, len(x))
        labels = np.atleast_1d(labels)
        xs, onehot = self._inputs(x, labels, None if indices is None else np.atleast_1d(indices))
        if self.config.kind == "gpr":
            features = np.hstack([xs, onehot]) if self.config.use_labels else xs
            mean, std = self.gpr.predict(features, return_std=True)
            std = np.broadcast_to(np.atleast_2d(std).reshape(len(x), -1), mean.shape)
        else:
            with torch.no_grad():
                mean, std = (t.numpy() for t in self.network(_tensor(xs), _tensor(onehot)))
        return self.s_scale.inverse(mean) + origins, std * self.s_scale.std


def base_frame(delta: np.ndarray, r: np.ndarray, base: np.ndarray) -> np.ndarray:
    """Delta = s - r expressed along (radial, tangential, vertical) directions of the arm's base at the lip's
    azimuth: the frame in which the base joint moves the lip tangentially and shoulder/elbow move it radially and
    vertically, whatever the base angle."""
    azimuth = np.arctan2(r[:, 1] - base[1], r[:, 0] - base[0])
    c, s = np.cos(azimuth), np.sin(azimuth)
    return np.stack([c * delta[:, 0] + s * delta[:, 1], -s * delta[:, 0] + c * delta[:, 1], delta[:, 2]], axis=1)


class DynamicPlanner:
    """The neural dynamic planner (Eq. 3.5) or, with ``full_observation``, the actor pi(r, s) of Fig. 3.10.

    The planner sees only Delta = s - r, expressed in the base frame of :func:`base_frame` (``base`` = the arm's
    base position; the thesis does not name the frame of Delta, and in a fixed world frame the same Delta needs
    different joint motions at different base angles). The full-observation actor sees r and s in the world frame.
    """

    def __init__(self, config: NDPConfig, max_step: float, base: np.ndarray, full_observation: bool = False,
                 seed: int = 0) -> None:
        self.config = config
        self.max_step = max_step
        self.base = np.asarray(base, dtype=float)
        self.full_observation = full_observation
        self.seed = seed

    def _features(self, r: np.ndarray, s: np.ndarray) -> np.ndarray:
        return np.hstack([r, s]) if self.full_observation else base_frame(s - r, r, self.base)

    def fit(self, r: np.ndarray, s: np.ndarray, actions: np.ndarray, trainer_factory: Callable) -> DynamicPlanner:
        cfg = self.config
        torch.manual_seed(self.seed)
        features = self._features(r, s)
        self.scale = Standardiser(features)
        inputs = _tensor(self.scale(features))
        if self.full_observation:
            self.network = FullObservationActor(cfg.hidden)
        else:
            self.network = NeuralDynamicPlanner(cfg.hidden, directions=cfg.mode == "direction")
        if cfg.mode == "direction" and not self.full_observation:
            target = torch.as_tensor(np.sign(actions) * (np.abs(actions) > 0.2 * self.max_step) + 1, dtype=torch.long)

            def objective(net, batch):
                xb, yb = batch
                return F.cross_entropy(net(xb).reshape(-1, 3), yb.reshape(-1)), {}
        else:
            target = _tensor(actions / self.max_step)

            def objective(net, batch):
                xb, yb = batch
                return 0.5 * ((net(xb) - yb) ** 2).sum(-1).mean(), {}  # Eq. 3.5
        fit_tensors(self.network, objective, [inputs, target], cfg.lr, cfg.steps, cfg.batch_size, trainer_factory)
        return self

    def act(self, r: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Joint deltas [base, shoulder, elbow] in radians, within the 5-degree limit."""
        inputs = _tensor(self.scale(self._features(np.atleast_2d(r), np.atleast_2d(s))))
        with torch.no_grad():
            out = self.network(inputs)[0]
        if self.config.mode == "direction" and not self.full_observation:
            return (out.argmax(-1).numpy() - 1.0) * self.max_step
        return np.clip(out.numpy(), -1.0, 1.0) * self.max_step


def build_subgoal_planner(cfg: SubgoalConfig, n_labels: int, n_subgoals: int = 1, seed: int = 0) -> SubgoalPlanner:
    """The sub-goal planner of a ``motion`` config (``MOTIONS.build(cfg, n_labels=..., n_subgoals=..., seed=...)``)."""
    return SubgoalPlanner(cfg, n_labels, n_subgoals, seed)


class StageClassifier:
    """c(x): the task (stage) label from the raw observation (3.2.1), an MLP trained with cross-entropy."""

    def __init__(self, cfg: ClassifierConfig, n_labels: int, seed: int = 0) -> None:
        self.cfg, self.n_labels, self.seed = cfg, n_labels, seed

    def fit(self, x: np.ndarray, labels: np.ndarray, trainer_factory: Callable) -> StageClassifier:
        from hrc_lab.motion.networks import TaskClassifier

        torch.manual_seed(self.seed)
        self.scale = Standardiser(x)
        self.network = TaskClassifier(x.shape[1], self.n_labels, self.cfg.hidden)

        def objective(net, batch):
            xb, yb = batch
            logits = net(xb)
            return F.cross_entropy(logits, yb), {"acc": accuracy(logits, yb)}

        tensors = [_tensor(self.scale(x)), torch.as_tensor(labels, dtype=torch.long)]
        fit_tensors(self.network, objective, tensors, self.cfg.lr, self.cfg.steps, self.cfg.batch_size,
                    trainer_factory)
        return self

    def scores(self, x: np.ndarray) -> np.ndarray:
        """Every label's logit, (N, n_labels)."""
        with torch.no_grad():
            return self.network(_tensor(self.scale(np.atleast_2d(x)))).numpy()

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.scores(x).argmax(-1)
