"""An alarm's identity and level: what a console, the alarm log and Keelson tell alarms apart by, and how
loud each is.

The status lists its alarms as texts for a person (`wire.messages.Status.alarms`), with the live figures
that explain them ("source dgps1: stale (3.1 s without data)"). A console that watched the texts saw a
raise and a clear every second as the figures moved. So each alarm also has:

- a **key** (`alarm_key`): its text with the figures that are values masked (`gateway.figures`), the same
  while the alarm stays up, different for a different alarm ("source dgps1" and "source dgps2";
  "beyond the warning circle" and "beyond the alarm circle", an escalation);
- a **level** (`alarm_level`): ``critical`` where DP cannot be trusted to hold the vessel now, else
  ``warning``. Not from a standard: the DP rules (IMO MSC/Circ.645, class notations) ask for alarms on
  loss of position reference and on excursions beyond set limits, and DP consoles show those red; the
  rest (a source stale while others carry on, a thruster out, the consequence analysis) asks for
  attention, not for the operator to take over now.
"""

from __future__ import annotations

from gateway.figures import without_figures

LEVELS = ("warning", "critical")

# Text starts (after the figures are masked) of the alarms that are critical in any mode, and in DP.
_CRITICAL = (
    "estimate lost:",  # no usable reference past integrity.lost_after_s: the estimate is a guess
)
_CRITICAL_IN_DP = (
    "estimate dead reckoning",  # DP holds on a dead-reckoned estimate: no position/heading reference
)
# Text ends of the excursions beyond the outer limit (`Pipeline._deviation_alarms`).
_CRITICAL_ENDINGS = ("beyond the alarm circle (# m)", "beyond the alarm limit (#°)")


# Alarms whose identity is their start alone: the rest of the text says what is missing and what DP does
# on it, which change while the alarm stays up.
_ONE_ALARM = ("estimate lost:", "estimate dead reckoning")


def alarm_key(text: str) -> str:
    """An alarm's identity: its text with the numbers that are values masked, so "stale (3.1 s without
    data)" growing to "(4.1 s ...)" is the same alarm still active, not one cleared and another raised.
    The digits of a name are not values: "source dgps1: stale (...)" and "source dgps2: stale (...)" are
    two alarms, as are "thruster 1 out of DP" and "thruster 2 out of DP".

    An estimate's alarm is its state alone (`_ONE_ALARM`): "no usable position and heading reference"
    becoming "no usable position reference" as the heading came back first was read as a clear and a new
    critical alarm, raised while the vessel was recovering and cleared a moment later. Dead reckoning that
    becomes lost is another alarm (an escalation, as the circles are)."""
    key = without_figures(text)
    return next((start for start in _ONE_ALARM if key.startswith(start)), key)


def alarm_level(text: str, mode: str) -> str:
    """``critical`` or ``warning`` (module docstring) for an alarm's text in the gateway's ``mode``."""
    key = without_figures(text)
    if key.startswith(_CRITICAL) or key.endswith(_CRITICAL_ENDINGS):
        return "critical"
    if mode == "dp" and key.startswith(_CRITICAL_IN_DP):
        return "critical"
    return "warning"
