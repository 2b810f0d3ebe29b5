"""Recording and replay: every run to MCAP (recorder), read back (reader), replayed in Rerun, verified by re-running it."""


class RecordingError(RuntimeError):
    """A recording that cannot be written, read or re-run; the message names the file."""


class RecorderLost(RuntimeError):
    """The recorder process of a run is gone (killed, crashed) while the run went on (``--record-lost stop``)."""


class RecorderFailed(RecorderLost):
    """The recorder process of a run could not start, or could not write the file (a full disk), or stopped
    making progress; the message names it and says why (exit status 1, as a run that failed)."""
