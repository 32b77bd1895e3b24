"""``reasoning=rf``: the Random Forest baseline of Sec. 4.4.1 (scikit-learn). One forest classifies P_o from the
flat observation; a second classifies P_g from [one-hot P_o, g_selected], mirroring the two-stage structure."""

from __future__ import annotations

import numpy as np
from sklearn.ensemble import RandomForestClassifier

from hrc_lab.env.robot.spec import StageObservation
from hrc_lab.reasoning.base import Reasoner
from hrc_lab.reasoning.configs import RandomForestConfig
from hrc_lab.reasoning.encoding import flat_vector, goal_table


class RandomForestReasoner(Reasoner):
    cfg: RandomForestConfig
    handles_missing_products = False

    def __init__(self, spec, cfg: RandomForestConfig, seed: int = 0) -> None:
        super().__init__(spec, cfg, seed)
        kwargs = dict(n_estimators=cfg.n_estimators, max_depth=cfg.max_depth, random_state=seed, n_jobs=1)
        self.forest_o = RandomForestClassifier(**kwargs)
        self.forest_g = RandomForestClassifier(**kwargs)

    def _stage_features(self, observations: list[StageObservation], o_index: np.ndarray) -> np.ndarray:
        goals = np.stack([goal_table(o, self.spec) for o in observations])
        return np.column_stack([np.eye(self.n_o)[o_index], goals[np.arange(len(o_index)), o_index]])

    def fit(self, observations: list[StageObservation], trainer=None) -> None:
        labels = self.labels(observations)
        self.forest_o.fit(np.stack([flat_vector(o, self.spec) for o in observations]), labels[:, 0])
        self.forest_g.fit(self._stage_features(observations, labels[:, 0]), labels[:, 1])

    def predict(self, observations: list[StageObservation]) -> np.ndarray:
        o_pred = self.forest_o.predict(np.stack([flat_vector(o, self.spec) for o in observations]))
        g_pred = self.forest_g.predict(self._stage_features(observations, o_pred))
        return np.column_stack([o_pred, g_pred])
