"""Progress on long work (tqdm): a co-simulation of many steps, a study of many runs.

A bar on stderr; where stderr is no terminal (a log file, CI) the same bar is written at
most every 5 s, so a log shows the work moving without a line per update.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from ..logs import quiet


@contextmanager
def progress_bar(total: int, what: str, unit: str, threshold: int = 0
                 ) -> Iterator[Callable[..., None] | None]:
    """A callback update(done, total[, failed]) drawing a bar of `total` `unit`s (and
    the failed ones), or None when the work is shorter than `threshold` units (not
    worth a bar)."""
    if total < threshold or quiet():  # -q: no bar either
        yield None
        return
    from tqdm import tqdm

    tty = getattr(sys.stderr, "isatty", lambda: False)()
    with tqdm(total=total, desc=what, unit=unit, unit_scale=True, file=sys.stderr,
              mininterval=0.1 if tty else 5.0, dynamic_ncols=tty) as bar:
        def update(done: int, _total: int, failed: int | None = None) -> None:
            if failed is not None:
                bar.set_postfix(failed=failed, refresh=False)
            bar.update(done - bar.n)

        yield update
