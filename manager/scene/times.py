"""A scene's times as they travel: whole nanoseconds in a signed 64-bit integer (docs/protocol.md).

:func:`nanoseconds` is the one conversion from float seconds (a TOML scene's ``macro_step``, ``duration`` and
micro-steps, the energy control's step sizes, ``--set`` values, an OSP or SSP file's step sizes and end time);
it raises :class:`NotATime` saying why a float is no such time: not a number, infinite, beyond 2**63 - 1 ns,
under 1 ns, or not a whole number of nanoseconds. Each caller names the file and key.
"""
from __future__ import annotations

import math

LONGEST_NS = 2**63 - 1  # the longest time a scene can state [ns]
LONGEST_TIME_S = LONGEST_NS * 1e-9  # the same [s], for messages
WHOLE = 1e-3  # [ns] how far from a whole number of nanoseconds a time may be (float seconds rarely hit one)


class NotATime(ValueError):
    """A float that is no time of a scene: ``expected`` says what a time is, the text adds what was given."""

    def __init__(self, expected: str, seconds: object) -> None:
        self.expected = expected
        super().__init__(f"{expected}, got {seconds!r}" + (" s" if isinstance(seconds, float) else ""))


def nanoseconds(seconds: float, whole: bool = True) -> int:
    """``seconds`` [s] as a count of nanoseconds from 1 to ``LONGEST_NS``; ``whole``: within ``WHOLE`` of a whole
    number (else rounded to the nearest). Raises :class:`NotATime`."""
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or math.isnan(seconds):
        raise NotATime("expected a number of seconds", seconds)
    count = seconds * 1e9  # inf beyond 1.8e299 s, which the next line refuses
    if not count <= LONGEST_NS:  # compared exactly: 2**63 ns (9.223372036854776e9 s as a float) is refused
        raise NotATime(f"expected at most {LONGEST_TIME_S:.4g} s (times are counted in signed 64-bit nanoseconds)",
                       seconds)
    rounded = round(count) if count >= 0.5 else 0  # -inf too
    if rounded < 1:
        raise NotATime("expected at least 1 ns (times are counted in whole nanoseconds)", seconds)
    if whole and abs(count - rounded) > WHOLE:
        raise NotATime("expected a whole number of nanoseconds", seconds)
    return rounded
