"""The learning-rate schedules of :class:`hrc_lab.training.SupervisedModule`, by name. Light (no torch, no Hydra):
config schemas validate against them without importing :mod:`hrc_lab.config`, whose import registers every schema
(and so imports the config groups' packages)."""

LR_SCHEDULES = ("constant", "cosine")
