"""The simulator: plant, sea, sensors, faults, transports. Importing it first decides whether the compiled
hot path is used (`wire.compiled`): some of its modules are compiled."""

import wire as _wire  # noqa: F401  (first: decides whether the compiled hot path is used, `wire.compiled`)
