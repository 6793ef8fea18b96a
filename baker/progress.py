"""Progress bars on long work (tqdm on stderr; silent when not a terminal
or when the caller asks for none)."""
from __future__ import annotations

import sys


class _Silent:
    def update(self, n=1):
        pass

    def set_postfix(self, **kw):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def bar(total, desc, unit="it", enabled=True):
    """A progress bar with .update(n), .set_postfix(...), .close(), usable
    as a context manager; a silent one when not enabled."""
    if not enabled:
        return _Silent()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr, disable=None, unit_scale=True)
