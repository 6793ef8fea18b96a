"""A bake's texel tiles on Dask distributed workers (`--workers`,
`--scheduler`).

The coordinator (the `voxbake bake` process) does every stage as before;
the texel stage's tiles (executor.py) go to the workers as Dask tasks,
with what they share (ShadeContext: BVH, surfaces, lights, solution) sent
to each worker once. Results come back to their tile's place, so the
file is the same bytes on any number of workers. Dask replaces a worker
that dies (its nanny) and runs its tasks again elsewhere; a task that
raises is tried RETRIES more times, then the bake fails naming the tile.

Dask's TCP protocol runs pickled code, so a scheduler beyond this machine
must be reached over TLS (`tls://`, with certificates from the flags or
Dask's config); plain `tcp://` there is refused unless the user says
`--insecure`.
"""
from __future__ import annotations

import ipaddress
import logging
import socket
import time
from contextlib import contextmanager
from dataclasses import fields, is_dataclass

import numpy as np

from ..errors import VoxgiError
from .executor import TILE, Executor, run_task, timed, version_mismatch, versions

RETRIES = 2           # a task that raises runs this many more times before the bake fails
WORKER_WAIT_S = 60.0  # how long a bake waits for an existing cluster's first worker
POLL_S = 0.25         # Ctrl-C is looked at this often while tiles run


def _is_loopback(host: str) -> bool:
    """Does host (a name or an address) reach this machine only? A name
    counts when every address it resolves to is loopback."""
    host = host.strip("[]")
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(i[4][0].split("%")[0]).is_loopback for i in infos)


def check_scheduler(address: str, insecure: bool) -> str:
    """The scheduler's address, checked: tls:// anywhere; tcp:// (or no
    scheme) on this machine only, unless insecure. Raises VoxgiError in
    one line otherwise."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    scheme = scheme.lower()
    host = rest.rsplit(":", 1)[0] if ":" in rest and not rest.endswith("]") else rest
    if not host or not rest:
        raise VoxgiError(f"--scheduler {address}: give an address as tls://HOST:PORT (or tcp://127.0.0.1:PORT)")
    if scheme == "tls":
        return f"tls://{rest}"
    if scheme != "tcp":
        raise VoxgiError(f"--scheduler {address}: the scheme must be tls:// or tcp://")
    if not _is_loopback(host) and not insecure:
        raise VoxgiError(f"--scheduler {address}: Dask's tcp:// runs pickled code from anyone who can reach the "
                         "port; beyond this machine use tls:// with certificates (--tls-ca-file, --tls-cert, "
                         "--tls-key), or add --insecure on a network you trust")
    return f"tcp://{rest}"


def security_for(ca=None, cert=None, key=None):
    """distributed's Security for tls:// from the certificate files given
    (None: Dask's own config, distributed.comm.tls, applies)."""
    if not (ca or cert or key):
        return None
    import os

    from distributed.security import Security
    if not (ca and cert and key):
        raise VoxgiError("TLS needs all three of --tls-ca-file, --tls-cert and --tls-key")
    for path in (ca, cert, key):
        if not os.path.isfile(path) or not os.access(path, os.R_OK):
            raise VoxgiError("no such readable file", path)
    return Security(tls_ca_file=ca, tls_client_cert=cert, tls_client_key=key, require_encryption=True)


def nbytes(obj, seen=None) -> int:
    """The bytes of the arrays in obj (records, tuples, lists, dicts):
    about what pickling it sends."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return obj.nbytes
    if is_dataclass(obj) and not isinstance(obj, type):
        return sum(nbytes(getattr(obj, f.name), seen) for f in fields(obj))
    if isinstance(obj, dict):
        return sum(nbytes(v, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(nbytes(v, seen) for v in obj)
    return 0


def _retried(dask_scheduler=None, keys=(), asked=0) -> int:
    """(On the scheduler.) Runs the tasks `keys` needed beyond their
    first: workers that died holding them, and retries after errors."""
    n = 0
    for k in keys:
        ts = dask_scheduler.tasks.get(k)
        if ts is not None:
            n += int(ts.suspicious) + max(0, asked - int(ts.retries or 0))
    return n


def _one_line(exc) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1] if text else ''}".strip().rstrip(":")


class DaskExecutor(Executor):
    """Tiles as Dask tasks on a cluster's workers (client: a
    distributed.Client; where: 'local cluster' or the scheduler's
    address; threads: numba threads per task, 0: the worker's all)."""

    def __init__(self, client, where: str, store=None, tile: int = TILE, threads: int = 0):
        super().__init__(store, tile)
        self.client = client
        self.where = where
        self.threads = int(threads)
        self._calls = 0
        self._checked = False
        self._versions = versions()
        self.workers = len(client.scheduler_info().get("workers", {}))

    def check_workers(self):
        """Refuses (one line) a worker whose voxgi, numpy or numba differ
        from ours, or that cannot import voxgi at all."""
        ours = versions()
        try:
            got = self.client.run(versions)
        except Exception as e:   # a worker without voxgi: the import fails there
            raise VoxgiError(f"a worker of {self.where} cannot run voxgi ({_one_line(e)}): install voxgi on every "
                             "worker") from None
        for addr, theirs in sorted(got.items()):
            bad = version_mismatch(theirs, ours)
            if bad:
                raise VoxgiError(f"worker {addr} runs {bad}: install the same voxgi, numpy and numba on every "
                                 "worker")
        self.workers = len(got)

    def _share(self, obj):
        self._check()
        self.counts["bytes_sent"] += nbytes(obj) * max(1, self.workers)
        with timed(self.counts):
            return self.client.scatter(obj, broadcast=True, hash=False)

    def _release(self, handle):
        handle.release()

    def start(self):
        self.check_workers()
        self._checked = True

    def _check(self):
        if not self._checked:
            self.check_workers()
            self._checked = True

    def _run(self, fn, items, handles, name):
        from distributed import wait

        from ..startup import checkpoint
        if not items:
            return
        self._check()
        self._calls += 1
        keys = [f"voxgi-{name}-{getattr(t, 'number', j)}-{self._calls}-{id(self)}" for j, t in enumerate(items)]
        self.counts["bytes_sent"] += sum(nbytes(t) for t in items)
        futures = self.client.map(run_task, items, fn=fn, shared=list(handles), versions=self._versions,
                                  threads=self.threads, key=keys, retries=RETRIES, pure=False)
        index = {f.key: j for j, f in enumerate(futures)}
        pending = set(futures)
        try:
            while pending:
                try:
                    done, pending = wait(pending, timeout=POLL_S, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    checkpoint()
                    continue
                for f in sorted(done, key=lambda f: index[f.key]):
                    j = index[f.key]
                    if f.status != "finished":
                        exc = f.exception() if f.status == "error" else None
                        if isinstance(exc, VoxgiError):
                            raise VoxgiError(str(exc)) from None
                        raise VoxgiError(f"{items[j].describe()} failed {RETRIES + 1} times on {self.where}"
                                         + (f": {_one_line(exc)}" if exc is not None else f" ({f.status})"))
                    t0 = time.perf_counter()
                    r = f.result()
                    self.counts["transfer_seconds"] += time.perf_counter() - t0
                    self.counts["bytes_received"] += nbytes(r)
                    yield j, r
            self.counts["retries"] += int(self.client.run_on_scheduler(_retried, keys=keys, asked=RETRIES))
        finally:
            self.client.cancel([f for f in futures if not f.done()])
            del futures


@contextmanager
def dask_executor(workers=0, scheduler=None, threads=0, insecure=False, tls=(None, None, None), tile=TILE):
    """A DaskExecutor on a local cluster of `workers` processes (numba
    threads each: `threads`, 0: one) or on the cluster at `scheduler`
    (its workers' numba threads: `threads`, 0: all they have); closed
    (the local cluster stopped) on leaving."""
    from distributed import Client, LocalCluster
    logging.getLogger("distributed").setLevel(logging.ERROR)
    cluster = None
    client = None
    try:
        if scheduler:
            address = check_scheduler(scheduler, insecure)
            security = security_for(*tls)
            try:
                client = Client(address, security=security, timeout=f"{WORKER_WAIT_S}s")
                client.wait_for_workers(1, timeout=WORKER_WAIT_S)
            except (OSError, TimeoutError) as e:
                raise VoxgiError(f"--scheduler {scheduler}: no scheduler with workers answers ({_one_line(e)})") \
                    from None
            where = address
            per_task = int(threads)
        else:
            n = int(threads) or 1
            cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True, host="127.0.0.1",
                                   dashboard_address=None, silence_logs=logging.ERROR,
                                   # (its HTTP server, dashboard off: on a free port of this machine's loopback)
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                   env={"NUMBA_NUM_THREADS": str(n), "OMP_NUM_THREADS": "1"})
            client = Client(cluster)
            client.wait_for_workers(int(workers))
            where = "local cluster"
            per_task = n
        ex = DaskExecutor(client, where, tile=tile, threads=per_task)
        try:
            yield ex
        finally:
            ex.close()
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
