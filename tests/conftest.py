"""Shared fixtures: scenes built on the fly from the generator, JIT warm-up."""
import os

import numpy as np
import pytest

from baker import bvh as bvh_mod
from baker import surfaces
from baker.scene import load_scene


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("scenes")


@pytest.fixture(scope="session")
def make_scene(scene_dir):
    """make_scene(builder, name) -> Scene: saves a GltfBuilder and loads it back."""
    cache = {}

    def make(builder, name):
        if name not in cache:
            path = os.path.join(scene_dir, name + ".glb")
            builder.save(path)
            cache[name] = load_scene(path)
        return cache[name]
    return make


@pytest.fixture(scope="session")
def cornell():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return load_scene(os.path.join(here, "scenes", "cornell_box.glb"))


@pytest.fixture(scope="session")
def jit_warm(cornell):
    """Compiles the ray kernels once per session (numba cache=True keeps them)."""
    tree = bvh_mod.build_scene_bvh(cornell)
    tree.closest(np.zeros((1, 3)), np.ones((1, 3)))
    tree.occluded(np.zeros((1, 3)), np.ones((1, 3)))
    return tree, surfaces.pack(cornell)
