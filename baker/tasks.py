"""Running a stage's pure tasks here or on an executor (bake/executor.py)."""
from __future__ import annotations


def run_tasks(executor, fn, items, shared, name, done=None) -> list:
    """[fn(item, shared) for item in items]: in this process, in order,
    Ctrl-C looked at between them (executor None), or on `executor` with
    `shared` sent to its workers once; done(j, result) as item j is done."""
    from .startup import checkpoint
    if executor is None:
        out = []
        for j, item in enumerate(items):
            checkpoint()
            out.append(fn(item, shared))
            if done is not None:
                done(j, out[-1])
        return out
    handle = executor.share(shared)
    try:
        return executor.map(fn, items, handle, name=name, done=done)
    finally:
        executor.release(handle)
