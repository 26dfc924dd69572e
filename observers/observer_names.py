"""The names of the registered observers, without importing them.

`observers.factory` imports the observer base classes and the passive tuning (numpy); the command line
lists the names in ``--help`` and must not pay for that. A test holds this tuple equal to
`observers.factory.OBSERVER_TYPES`, in its order.
"""

OBSERVER_NAMES: tuple[str, ...] = ("passive", "gain_scheduled", "mmae", "sdre", "ekf", "memory")
