"""A source's state (ok / suspect / rejected / stale), with the reason, and readmission after a rejection."""

from __future__ import annotations

from dataclasses import dataclass

from mypy_extensions import mypyc_attr

from gateway.figures import without_figures

NS = 1_000_000_000
OK, SUSPECT, REJECTED, STALE = "ok", "suspect", "rejected", "stale"
STATES = (OK, SUSPECT, REJECTED, STALE)


@mypyc_attr(native_class=False)
@dataclass(frozen=True)
class StateChange:
    """A source changed state: when, which source and role, from what to what, and why (for people)."""

    stamp_ns: int
    source: str
    role: str
    old: str
    new: str
    reason: str

    @property
    def text(self) -> str:
        why = f": {self.reason}" if self.reason else ""
        return f"{reference_name(self.role, self.source)}: {self.old} -> {self.new}{why}"


def reference_name(role: str, source: str) -> str:
    """How a source in a role is named to people: ``position reference dgps1``; a thruster link's feedback,
    whose role and usual source name are both "thrusters", as ``reference thrusters (thruster feedback)``
    (``thrusters reference thrusters`` read as a slip)."""
    if role == "thrusters":
        return f"reference {source} (thruster feedback)"
    return f"{role} reference {source}"


def reason_kind(reason: str) -> str:
    """What a reason says, without its figures: its part before the first colon (the test's name, or
    ``diverges from dgps2 by 1.71 m (limit 1 m)``) with its values as ``#`` by the alarm log's rule
    (`gateway.figures.without_figures`). Names that end in digits (``dgps2``) are kept: a divergence
    from another source is another kind."""
    return without_figures(reason.split(":")[0])


class SourceState:
    """The state machine of one source in one role.

    - a failed test: ``rejected`` with its reason, not used;
    - passing again: ``suspect`` (readmitting), not used, until it has passed for ``readmit_ns``; then ``ok``
      (or at once when its data show the fault was a spike that is over: `readmit_now`);
    - a soft alarm (two references diverge, nobody can tell which is wrong): ``suspect`` but still used;
    - no data within the source's timeout: ``stale``; its next passing fix makes it ``ok`` again (silence is
      not a fault of the data, and the jump test bounds what the first fix after a gap may be). A source
      whose data keep coming and failing is not silent: it stays ``rejected`` with the reason of its
      latest failure (`failing`), and goes ``stale`` only once nothing has come for its timeout.
    """

    def __init__(self, source: str, role: str, readmit_ns: int) -> None:
        self.source = source
        self.role = role
        self.readmit_ns = readmit_ns
        self.state = STALE
        self.reason = "no data yet"
        self.since_ns = 0
        self._passing_since: int | None = None
        self._soft: str = ""
        self._was_rejected = False  # went stale while rejected or readmitting: readmit when it returns
        self._reads_refused = False  # rejected for its reads alone (`refuse_reads`): no value failed a test
        self.failed_ns = 0  # when data last failed a test
        self.changes: list[StateChange] = []

    @property
    def usable(self) -> bool:
        """Its data may go into the estimate: ok, or suspect only by a soft alarm (not readmitting)."""
        return self.state == OK or (self.state == SUSPECT and self._passing_since is None)

    def _set(self, now_ns: int, state: str, reason: str) -> None:
        """A change of state, or of the kind of reason in a state other than ok, is an event; the same
        state for the same kind of reason with other figures (a divergence of 1.54 m, then 1.50 m) only
        updates the reason, which the status shows (`reason_kind`)."""
        if state != self.state or (
            state != OK and reason != self.reason and reason_kind(reason) != reason_kind(self.reason)
        ):
            self.changes.append(StateChange(now_ns, self.source, self.role, self.state, state, reason))
            self.since_ns = now_ns
        self.state, self.reason = state, reason

    def fail(self, now_ns: int, reason: str) -> None:
        self._passing_since = None
        self._reads_refused = False
        self.failed_ns = now_ns
        self._set(now_ns, REJECTED, reason)

    def refuse_reads(self, now_ns: int, reason: str) -> None:
        """Its reads keep coming and its decoder refuses them all (`ReferenceMonitor.refresh`): rejected,
        with that reason, not stale. No value of it failed a test, so its first good one is used at once,
        as after a silence; one that was out for a test's failure (rejected, readmitting) stays owed its
        readmission."""
        owed = (
            (self.state == REJECTED and not self._reads_refused)
            or self._passing_since is not None
            or (self.state == STALE and self._was_rejected)
        )
        self._reads_refused = not owed
        self._was_rejected = owed
        self._passing_since = None
        self.failed_ns = now_ns
        self._set(now_ns, REJECTED, reason)

    def failing(self, now_ns: int, timeout_ns: int) -> bool:
        """Rejected, and data failed a test within ``timeout_ns``: the source talks, its data are refused."""
        return self.state == REJECTED and now_ns - self.failed_ns <= timeout_ns

    def passed(self, now_ns: int) -> None:
        """The latest data passed every test."""
        if self.state == OK and self._passing_since is None and not self._soft:
            return  # ok and staying ok (every fix of a healthy source): nothing changes
        if self._reads_refused:  # (its reads decode again, and no value of it was wrong: in use at once)
            self._reads_refused = False
        elif self.state == REJECTED or (self.state == STALE and self._was_rejected):
            self._was_rejected = False
            self._passing_since = now_ns
            self._set(now_ns, SUSPECT, f"readmitting: passes again, in use after {self.readmit_ns / NS:g} s")
            return
        if self._passing_since is not None:
            if now_ns - self._passing_since < self.readmit_ns:
                return
            self._passing_since = None
        if self._soft:
            self._set(now_ns, SUSPECT, self._soft)
        else:
            self._set(now_ns, OK, "")

    def readmit_now(self, now_ns: int, reason: str) -> None:
        """Readmitting, and the source has shown that what failed was over (a heading back on its track
        after a spike, `ReferenceMonitor`): in use at once, without waiting out ``readmit_ns``."""
        if self._passing_since is None or self.state != SUSPECT:
            return
        self._passing_since = None
        self._set(now_ns, SUSPECT if self._soft else OK, self._soft or reason)
        self.reason = self._soft  # (the reason is the change's; an ok source has none)

    def soft(self, now_ns: int, reason: str) -> None:
        """Raise (non-empty reason) or clear (empty) a soft alarm; it shows as ``suspect`` while in use."""
        self._soft = reason
        if not reason and self.state == OK:
            return  # no alarm, none raised: nothing changes (asked for every fix)
        if self.state in (OK, SUSPECT) and self._passing_since is None:
            self._set(now_ns, SUSPECT if reason else OK, reason)

    def stale(self, now_ns: int, age_s: float) -> None:
        if self.state != STALE:
            self._was_rejected = (
                self.state == REJECTED and not self._reads_refused
            ) or self._passing_since is not None
            self._reads_refused = False
            self._passing_since = None
            self._set(now_ns, STALE, f"no data for {age_s:.1f} s")

    def drain(self) -> list[StateChange]:
        out, self.changes = self.changes, []
        return out
