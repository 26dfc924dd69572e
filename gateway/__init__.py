"""The gateway: sources, pipeline, outputs, service."""

import wire as _wire  # noqa: F401  (first: decides whether the compiled hot path is used, `wire.compiled`)
