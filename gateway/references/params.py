"""The integrity thresholds: the ``[integrity]`` config table (`gateway.config.model.IntegrityConfig`, where
each default is given with its reason; docs/integrity.md has the long form)."""

from gateway.config.model import POOLINGS
from gateway.config.model import IntegrityConfig as IntegrityParams

__all__ = ["POOLINGS", "IntegrityParams"]
