"""Many views across a Dask cluster: a turntable of a baked scan on 1 and 2 local workers."""

import os
import pathlib

import numpy as np
import pytest

import gridrt
from gridrt.views import render_views, turntable

MESHES = pathlib.Path(__file__).resolve().parents[4] / "shared" / "meshes"


@pytest.fixture(scope="module")
def baked_scan(tmp_path_factory):
    """dragon_res3 baked into a displaced micro-mesh at the defaults."""
    if not MESHES.is_dir():
        if os.environ.get("CI"):
            raise FileNotFoundError(f"{MESHES} is missing")
        pytest.skip("the shared meshes are not beside the project")
    out = tmp_path_factory.mktemp("baked") / "dragon.gltf"
    gridrt.bake(MESHES / "dragon_res3.ply", out)
    return out


def cluster(workers):
    distributed = pytest.importorskip("distributed") if not os.environ.get("CI") else __import__("distributed")
    # One thread per worker, and one for the CPU backend's own threads within it.
    cluster = distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
        env={"RAYON_NUM_THREADS": "1"},
    )
    return cluster, distributed.Client(cluster)


def test_a_turntable_renders_alike_on_one_and_two_workers(baked_scan, tmp_path):
    cameras = turntable(36)
    images = {}
    for workers in (1, 2):
        cluster_, client = cluster(workers)
        with cluster_, client:
            images[workers] = render_views(client, baked_scan, cameras, width=64, height=48, backend="cpu")
    assert len(images[1]) == 36
    for a, b in zip(images[1], images[2]):
        assert a.shape == (48, 64, 4)
        np.testing.assert_array_equal(a, b)
    # The views turn: no two neighbours alike.
    assert all(not np.array_equal(images[1][k], images[1][k + 1]) for k in range(35))
    # The same views as rendering them here.
    scene = gridrt.load(baked_scan, backend="cpu")
    np.testing.assert_array_equal(images[1][5], scene.render(64, 48, camera=cameras[5]))


def test_views_are_written_as_files_by_the_workers(tmp_path):
    cluster_, client = cluster(2)
    with cluster_, client:
        files = render_views(
            client, None, turntable(4), width=32, height=24, levels=1, backend="cpu",
            output=str(tmp_path / "view_{:02d}.png"),
        )
    assert files == [str(tmp_path / f"view_{k:02d}.png") for k in range(4)]
    assert all(pathlib.Path(f).stat().st_size > 0 for f in files)


def test_a_turntable_needs_a_view():
    with pytest.raises(ValueError):
        turntable(0)
