"""The bake's texel tiles on Dask workers (bake/executor.py, bake/cluster.py):
the same bytes as the plain bake on a cluster of two worker processes,
after a worker is killed mid-bake, and after a resume; refusals in one
line; the workers load the kernels from numba's cache."""
import os
import signal
import threading
import time

import numpy as np
import pytest

from baker.bake import bake_config, bake_scene, write_bake
from baker.bake.executor import LocalExecutor, Tile, TileStore
from baker.bake.pipeline import Checkpoint
from baker.errors import VoxgiError
from scenes.generate import thin_wall
from tests.conftest import cli

distributed = pytest.importorskip("distributed")

SMALL_TILE = 256   # many tiles from a small bake: a kill lands while some run


def small(**kw):
    return bake_config("default", resolution=16, photons=20_000, direct_vpls=2048, texel_density=24, **kw)


def baked_bytes(path, result):
    write_bake(str(path), result.bake)
    with open(path, "rb") as f:
        return f.read()


@pytest.fixture(scope="module")
def cluster():
    from baker.bake.cluster import dask_executor
    with dask_executor(workers=2, tile=SMALL_TILE) as ex:
        yield ex


@pytest.fixture(scope="module")
def local_bytes(tmp_path_factory, cornell, make_scene):
    """The plain bakes (in this process, tiles of the default size)."""
    out = {}
    d = tmp_path_factory.mktemp("local")
    for name, scene in (("cornell", cornell), ("thin_wall", make_scene(thin_wall(), "cluster_thin_wall"))):
        out[name] = (scene, baked_bytes(d / f"{name}.glb", bake_scene(scene, small())))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cornell", "thin_wall"])
def test_two_workers_write_the_same_bytes(cluster, local_bytes, tmp_path, name):
    scene, want = local_bytes[name]
    before = dict(cluster.named)
    result = bake_scene(scene, small(), executor=cluster)
    ran = {k: v - before.get(k, 0) for k, v in cluster.named.items()}
    # the texels went out as tiles, the photons and the solver's gathers as blocks
    assert ran["tile"] > 4 and ran["photons"] >= 1 and ran["voxels"] >= 2, ran   # a block per bounce gathered
    assert baked_bytes(tmp_path / "w.glb", result) == want
    assert "2 (local cluster)" in result.run


@pytest.mark.slow
def test_the_bounces_by_lines_on_two_workers_write_the_same_bytes(cluster, cornell, tmp_path):
    """--gather-rays 0: the bounces go out as blocks of direction
    families, each block's sums added in block order on the coordinator."""
    want = baked_bytes(tmp_path / "p.glb", bake_scene(cornell, small(gather_rays=0)))
    before = cluster.named.get("families", 0)
    result = bake_scene(cornell, small(gather_rays=0), executor=cluster)
    assert cluster.named["families"] - before > 10
    assert baked_bytes(tmp_path / "w.glb", result) == want


@pytest.mark.parametrize("gather_rays", [None, 0])
def test_any_split_and_order_of_the_tasks_gives_the_same_solution(cornell, gather_rays):
    """The solve's tasks handed back last first, and its gathers split in
    blocks as for three workers: the same solution, bit for bit, as the
    plain solve (the photons' and the lines' partial sums are added in
    block order; a voxel's gather is its own)."""
    from baker.presets import solver_config
    from baker.solve import solve
    kw = {} if gather_rays is None else {"gather_rays": gather_rays}
    cfg = solver_config("default", resolution=16, photons=150_000, **kw)
    plain = solve(cornell, cfg)
    ex = Shuffled(workers=3)
    shuffled = solve(cornell, cfg, executor=ex)
    assert ex.named["photons"] >= 3   # 150,000 photons: three blocks
    assert ex.named["families" if gather_rays == 0 else "voxels"] > 3
    for a, b in ((plain.irradiance, shuffled.irradiance), (plain.photon_power, shuffled.photon_power),
                 (plain.photon_centroid, shuffled.photon_centroid)):
        assert np.array_equal(a, b)
    assert plain.info["photons_landed"] == shuffled.info["photons_landed"]


@pytest.mark.slow
def test_a_killed_worker_costs_nothing(cluster, local_bytes, tmp_path):
    """SIGKILL to a worker while it runs a tile: Dask starts another, the
    tile runs again, the file is the same bytes and the retry is counted."""
    scene, want = local_bytes["cornell"]
    client = cluster.client
    pids = client.run(os.getpid)
    killed = []

    def killer():
        end = time.time() + 120
        while time.time() < end and not killed:
            for addr, keys in client.processing().items():
                if any(str(k).startswith("voxgi-tile-") for k in keys) and addr in pids:
                    os.kill(pids[addr], signal.SIGKILL)
                    killed.append(addr)
                    return
            time.sleep(0.005)
    retries = cluster.counts["retries"]
    t = threading.Thread(target=killer, daemon=True)
    t.start()
    result = bake_scene(scene, small(), executor=cluster)
    t.join()
    assert killed, "no tile was seen running"
    assert baked_bytes(tmp_path / "k.glb", result) == want
    assert cluster.counts["retries"] > retries
    client.wait_for_workers(2, timeout=120)   # the nanny's new worker, for the tests after


@pytest.mark.slow
def test_a_worker_of_other_versions_is_refused(cluster, cornell):
    import numba
    client = cluster.client
    real = numba.__version__
    one = sorted(client.scheduler_info()["workers"])[0]
    client.run(lambda: setattr(numba, "__version__", "0.0.1"), workers=[one])
    try:
        with pytest.raises(VoxgiError) as e:
            bake_scene(cornell, small(), executor=cluster)
        msg = str(e.value)
        assert "numba 0.0.1" in msg and real in msg and "\n" not in msg
    finally:
        # numba stamps its cache index with the version it read when a
        # module was imported: the voxgi modules imported there while it
        # was patched would miss the cache for good, so that worker starts
        # over (its nanny gives a fresh process)
        client.run(lambda: setattr(numba, "__version__", real), workers=[one])
        client.restart_workers([one])
        client.wait_for_workers(2, timeout=120)


@pytest.mark.slow
def test_workers_load_kernels_from_the_cache(cluster, local_bytes):
    """After tiles ran on them (the cache warm from the plain bakes), no
    numba kernel of voxgi was compiled inside a worker."""
    bake_scene(local_bytes["cornell"][0], small(), executor=cluster)

    def compiled():
        import sys

        from numba.core.dispatcher import Dispatcher
        hits = misses = 0
        for name, mod in list(sys.modules.items()):
            if not name.startswith("baker.") or mod is None:
                continue
            for obj in vars(mod).values():
                if isinstance(obj, Dispatcher):
                    hits += sum(obj.stats.cache_hits.values())
                    misses += sum(obj.stats.cache_misses.values())
        return hits, misses
    for addr, (hits, misses) in cluster.client.run(compiled).items():
        assert hits > 0 and misses == 0, (addr, hits, misses)


class Interrupted(LocalExecutor):
    """Stops the bake (as Ctrl-C does at a checkpoint) after k tiles."""

    def __init__(self, k, tile=SMALL_TILE):
        super().__init__(tile=tile)
        self.k = k

    def _run(self, fn, items, handles, name):
        for j, r in super()._run(fn, items, handles, name):
            if name == "tile" and self.named.get("tile", 0) >= self.k:
                raise KeyboardInterrupt
            yield j, r


class Shuffled(LocalExecutor):
    """Runs every task here but hands the results back last first, and
    splits the solver's gathers as for `workers` workers: what a cluster
    may do."""

    def __init__(self, workers=3, tile=SMALL_TILE):
        super().__init__(tile=tile)
        self.workers = workers
        self.where = "shuffled"

    def _run(self, fn, items, handles, name):
        done = [fn(item, *handles) for item in items]
        for j in reversed(range(len(done))):
            yield j, done[j]


def test_resume_skips_the_solve_and_the_finished_tiles(local_bytes, tmp_path, monkeypatch):
    scene, want = local_bytes["cornell"]
    folder = str(tmp_path / "ck")
    with pytest.raises(KeyboardInterrupt):
        bake_scene(scene, small(), executor=Interrupted(7), checkpoint=Checkpoint(folder))
    stored = os.listdir(os.path.join(folder, "tiles"))
    assert len(stored) == 7 and os.path.exists(os.path.join(folder, "solution.npz"))
    # without --resume the folder is refused (it would mix two bakes)
    with pytest.raises(VoxgiError, match="--resume"):
        bake_scene(scene, small(), checkpoint=Checkpoint(folder))
    import importlib
    solve_mod = importlib.import_module("baker.solve")   # (the package's `solve` attribute is the function)

    def no_solve(*a, **k):
        raise AssertionError("the solve ran again")
    monkeypatch.setattr(solve_mod, "solve", no_solve)
    ex = LocalExecutor(tile=SMALL_TILE)
    result = bake_scene(scene, small(), executor=ex, checkpoint=Checkpoint(folder, resume=True))
    assert ex.counts["tiles_resumed"] == 7 and ex.counts["tasks"] > 0
    assert baked_bytes(tmp_path / "r.glb", result) == want


def test_a_checkpoint_of_another_scene_or_settings_is_refused(local_bytes, tmp_path):
    scene, _ = local_bytes["cornell"]
    folder = str(tmp_path / "ck")
    with pytest.raises(KeyboardInterrupt):
        bake_scene(scene, small(), executor=Interrupted(1), checkpoint=Checkpoint(folder))
    other = local_bytes["thin_wall"][0]
    with pytest.raises(VoxgiError, match="another scene or other settings"):
        bake_scene(other, small(), checkpoint=Checkpoint(folder, resume=True))
    with pytest.raises(VoxgiError, match="another scene or other settings"):
        bake_scene(scene, small(seed=3), checkpoint=Checkpoint(folder, resume=True))


def test_damaged_tiles_and_records_are_shaded_again_or_refused(tmp_path):
    """A stored tile that is not whole, or of the wrong shape, is shaded
    again; a solution record that is damaged is refused in one line."""
    store = TileStore(str(tmp_path / "ck"), "x" * 64, resume=False)
    t = Tile(0, "sharp", np.zeros((4, 3)), np.zeros((4, 3)), np.ones(4, bool), None, 10, True)
    from baker.bake.executor import TileResult
    store.put(t.key(), TileResult(np.ones((4, 3)), np.ones(4, np.int64), 5))
    assert store.get(t.key(), 4).rays == 5
    assert store.get(t.key(), 5) is None   # another tile's size
    path = store._path(t.key())
    with open(path, "r+b") as f:
        f.truncate(40)
    assert store.get(t.key(), 4) is None
    with open(os.path.join(store.folder, "solution.npz"), "wb") as f:
        f.write(b"PK\x03\x04 not a record")
    with pytest.raises(VoxgiError, match="damaged checkpoint record"):
        store.get_solution()


def test_records_round_trip_exactly(cornell):
    """The solve's result through the checkpoint's record format: every
    array and value back as it was (the resumed file's bytes depend on it)."""
    from baker.bake.executor import TileStore
    from baker.scene import prepare
    from baker.solve import solve
    import tempfile
    sol = solve(prepare(cornell), small().solver)
    with tempfile.TemporaryDirectory() as d:
        store = TileStore(d, "y" * 64, resume=False)
        store.put_solution(sol)
        back = store.get_solution()
    assert back.info == sol.info and back.bounce_power == sol.bounce_power and back.stop_reason == sol.stop_reason
    for name in ("irradiance", "radiosity", "photon_power", "photon_centroid"):
        np.testing.assert_array_equal(getattr(back, name), getattr(sol, name))
    for f in sol.voxels.__dataclass_fields__:
        a, b = getattr(sol.voxels, f), getattr(back.voxels, f)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b


@pytest.mark.parametrize("address,insecure,ok", [
    ("tcp://127.0.0.1:8786", False, True), ("localhost:8786", False, True), ("tls://10.1.2.3:8786", False, True),
    ("tcp://10.1.2.3:8786", False, False), ("tcp://10.1.2.3:8786", True, True), ("10.1.2.3:8786", False, False),
    ("ucx://10.1.2.3:8786", True, False), ("tcp://", False, False)])
def test_scheduler_addresses(address, insecure, ok):
    from baker.bake.cluster import check_scheduler
    if ok:
        check_scheduler(address, insecure)
    else:
        with pytest.raises(VoxgiError):
            check_scheduler(address, insecure)


@pytest.mark.parametrize("flags,message", [
    (["--scheduler", "tcp://10.1.2.3:8786"], "tls://"),
    (["--resume"], "--resume needs --checkpoint"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with"),
    (["--tls-cert", "c.pem"], "for --scheduler"),
    (["--scheduler", "tls://10.1.2.3:8786", "--tls-ca-file", "/nonexistent/ca.pem", "--tls-cert", "c",
      "--tls-key", "k"], "no such readable file")])
def test_cluster_flags_are_refused_before_any_work(tmp_path, flags, message):
    out = str(tmp_path / "o.glb")
    status, stdout, stderr = cli("bake", "cornell_box", "-o", out, *flags)
    assert status == 2 and message in stderr and "Traceback" not in stderr, stderr
    assert len(stderr.strip().splitlines()) == 1 and not os.path.exists(out)


@pytest.mark.slow
def test_a_tile_that_keeps_failing_fails_the_bake_naming_it(cluster, cornell):
    import baker.lights
    client = cluster.client

    def broken():
        def boom(*a, **k):
            raise RuntimeError("boom")
        baker.lights.__dict__.setdefault("_real_irradiance", baker.lights.irradiance)
        baker.lights.irradiance = boom

    def mended():
        baker.lights.irradiance = baker.lights.__dict__.pop("_real_irradiance")
    client.run(broken)
    try:
        with pytest.raises(VoxgiError) as e:
            bake_scene(cornell, small(), executor=cluster)
    finally:
        client.run(mended)
    msg = str(e.value)
    assert msg.startswith("tile ") and "failed 3 times" in msg and "RuntimeError: boom" in msg and "\n" not in msg


CLI_SMALL = ("--resolution", "16", "--photons", "20000", "--direct-vpls", "2048", "--texel-density", "24")


@pytest.mark.slow
def test_the_command_on_workers_and_resumed_writes_the_same_bytes(tmp_path):
    """`voxbake bake` plain, with --workers 2, and with --checkpoint then
    --resume (every tile from the checkpoint): the same file."""
    files = {}
    for name, flags in (("plain", ()), ("workers", ("--workers", "2")),
                        ("checkpoint", ("--checkpoint", str(tmp_path / "ck"))),
                        ("resumed", ("--checkpoint", str(tmp_path / "ck"), "--resume"))):
        out = tmp_path / f"{name}.glb"
        status, stdout, stderr = cli("bake", "cornell_box", "-o", out, *CLI_SMALL, *flags)
        assert status == 0, stderr
        files[name] = out.read_bytes()
        if name == "workers":
            assert "2 (local cluster)" in stdout
        if name == "resumed":
            assert "from the checkpoint" in stdout and " 0 tiles" in stdout, stdout
    assert len(set(files.values())) == 1
