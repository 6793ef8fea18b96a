"""Progress bars on long work (tqdm on stderr; silent when not a terminal
or when the caller asks for none). Each step is also a checkpoint where
a command's Ctrl-C stops the work (startup.py)."""
from __future__ import annotations

import sys

from .startup import checkpoint


class Bar:
    """.update(n), .grow(n), .set_postfix(...), .close(); a context manager."""

    def __init__(self, inner=None):
        self.inner = inner

    def update(self, n=1):
        checkpoint()
        if self.inner is not None:
            self.inner.update(n)

    def grow(self, n):
        """The work turned out n units larger (or smaller) than announced."""
        if self.inner is not None and n:
            self.inner.total += n
            self.inner.refresh()

    def set_postfix(self, **kw):
        if self.inner is not None:
            self.inner.set_postfix(**kw)

    def close(self):
        if self.inner is not None:
            self.inner.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def bar(total, desc, unit="it", enabled=True) -> Bar:
    """A progress bar (silent when not enabled: still a checkpoint)."""
    if not enabled:
        return Bar()
    from tqdm import tqdm
    return Bar(tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr, disable=None, unit_scale=True))
