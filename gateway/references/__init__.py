"""Reference integrity: every position, heading and thruster-feedback source is tested before its data is
used, and no single source can take the estimate (docs/integrity.md).

- `params`: the thresholds (``[integrity]`` in the config) and their defaults.
- `state`: a source's state (ok / suspect / rejected / stale), its reason, readmission, the state-change
  events.
- `position`, `heading`: the per-fix tests of one source (quality, range, jump/rate, freeze, prediction,
  variance) and the smoothed track the votes compare.
- `voting`: median of three or more, pairwise divergence of two.
- `feedback`: thruster feedback range checks.
- `monitor`: all of it for a gateway's sources, what the pipeline talks to.
"""

from gateway.references.monitor import ReferenceMonitor, RoleHealth
from gateway.references.params import IntegrityParams
from gateway.references.state import StateChange

__all__ = ["IntegrityParams", "ReferenceMonitor", "RoleHealth", "StateChange"]
