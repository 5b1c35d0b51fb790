"""Progress reports: the ``progress(stage, done, total)`` callback every long-running step takes
(``report``) and a counter for steps done in several threads (``ProgressCounter``). The
library never prints; the command line renders these as a progress bar. A callback of the
wrong arguments is refused by :func:`tghop._errors.check_progress`.
"""

from __future__ import annotations

import threading
from typing import Callable, Optional

from ._errors import TGHopError

__all__ = [
    "ProgressCallback",
    "report",
    "ProgressCounter",
]


#: ``progress(stage, done, total)``: called by long-running steps. ``stage`` is a short
#: human-readable name ("hop 1", "clusters", "quilting"), ``done`` counts finished units
#: out of ``total``. A stage always ends with ``done == total``.
ProgressCallback = Callable[[str, int, int], None]


def report(progress: Optional[ProgressCallback], stage: str, done: int, total: int) -> None:
    """Call ``progress`` if one was given."""
    if progress is not None:
        if not callable(progress):
            raise TGHopError(f"progress must be a function progress(stage, done, total) or None, "
                             f"got {type(progress).__name__}")
        progress(stage, int(done), int(total))


class ProgressCounter:
    """``progress(stage, done, total)`` of steps done in several threads: ``counter(n)`` adds ``n`` steps and
    reports the sum (under a lock, so that the counts reported only grow, from whichever thread did the step).

    Parameters
    ----------
    progress : callable or None
        The callback (None: the steps are only counted).
    stage : str
    total : int
        The steps of the whole stage.
    """

    def __init__(self, progress, stage, total):
        self.progress, self.stage, self.total = progress, stage, total
        self.done = 0
        self._lock = threading.Lock()

    def __call__(self, n):
        with self._lock:
            self.done += n
            report(self.progress, self.stage, self.done, self.total)

    def relay(self):
        """A ``progress(stage, done, total)`` callback for a part of the work: each of its reports adds the
        steps its ``done`` gained since its last one (its own stage and total are not used)."""
        last = [0]

        def told(stage, done, total):
            if done > last[0]:
                self(done - last[0])
                last[0] = done

        return told
