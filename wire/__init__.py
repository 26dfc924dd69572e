"""The wire layer: codecs, messages, geodesy, MCAP. Importing it first decides whether the compiled hot
path is used (`wire.compiled`)."""

from wire import compiled as _compiled

_compiled.install()
