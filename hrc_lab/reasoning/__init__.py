"""Ch.4 reasoning module and its baselines; ``conf/reasoning/<name>.yaml`` selects one by ``name``."""

from hrc_lab.reasoning.configs import REASONERS


def build_reasoner(node, spec, seed: int = 0):
    """Instantiate the reasoning method a config node names (validated against its schema)."""
    return REASONERS.load(node.name)(spec, REASONERS.validate(node), seed=seed)


__all__ = ["REASONERS", "build_reasoner"]
