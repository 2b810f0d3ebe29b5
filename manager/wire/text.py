"""Text that came from the network (a subsystem's error, a log line, a description), made safe for a terminal.

A message's text can hold any bytes a peer chose; an ESC (``\\x1b``) starts a terminal control sequence
that can move the cursor, rewrite what is shown, set the window title or, on some terminals, answer
back. :func:`printable` writes every control character except newline and tab as its escape
(``\\x1b``), so the text reads the same and controls nothing.
"""
from __future__ import annotations

import re

# C0 controls but tab and newline, DEL, C1 controls; and the Unicode line/paragraph separators and bidi
# overrides, which also change what a terminal shows
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """``text`` with every control character but newline and tab written as its escape (``\\x1b``, ``\\u202e``)."""
    return _CONTROL.sub(lambda match: match.group().encode("unicode_escape").decode("ascii"), text)
