"""gridrt's hits against what users have: trimesh with Embree (embreex), on the same rays
through the shared meshes traced as triangles."""

import os
import pathlib

import numpy as np
import pytest

import gridrt

MESHES = pathlib.Path(__file__).resolve().parents[4] / "shared" / "meshes"
NAMES = ["bunny.obj", "teapot.obj", "dragon_res3.ply", "dragon_res4.ply"]


def embree_or_skip():
    """trimesh's Embree intersector, or a skip where it is not installed (CI installs it)."""
    if os.environ.get("CI"):
        import embreex  # noqa: F401
        import trimesh
    else:
        pytest.importorskip("embreex")
        trimesh = pytest.importorskip("trimesh")
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    return trimesh, RayMeshIntersector


def rays_through(lo, hi, count, seed):
    """Rays from a sphere around the box towards points inside it."""
    rng = np.random.default_rng(seed)
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo)
    away = rng.normal(size=(count, 3))
    origins = centre + radius * away / np.linalg.norm(away, axis=1, keepdims=True)
    targets = lo + rng.random((count, 3)) * (hi - lo)
    return origins, targets - origins


@pytest.mark.skipif(not MESHES.is_dir(), reason="the shared meshes are not beside the project")
@pytest.mark.parametrize("name", NAMES)
def test_hits_equal_embrees(name):
    trimesh, RayMeshIntersector = embree_or_skip()
    mesh = trimesh.load(MESHES / name, process=False, force="mesh")
    scene = gridrt.load(MESHES / name, levels=0, mode="triangles", backend="cpu")
    origins, directions = rays_through(mesh.bounds[0], mesh.bounds[1], 20_000, seed=len(name))
    ours = scene.intersect(origins, directions)
    locations, ray, tri = RayMeshIntersector(mesh).intersects_location(origins, directions, multiple_hits=False)
    theirs_prim = np.full(len(origins), -1)
    theirs_prim[ray] = tri
    theirs_t = np.full(len(origins), np.inf)
    theirs_t[ray] = np.linalg.norm(locations - origins[ray], axis=1) / np.linalg.norm(directions[ray], axis=1)

    both = (ours.prim >= 0) & (theirs_prim >= 0)
    assert (ours.prim >= 0).mean() > 0.2, "too few rays hit to compare"
    # Hit or miss alike, but for rays that graze an edge.
    assert ((ours.prim >= 0) == (theirs_prim >= 0)).mean() >= 0.999
    # The same triangle (by its corners: a file may hold a triangle twice, gridrt keeps the
    # first and Embree either), but where a ray meets an edge or corner two triangles share.
    corners = lambda t: np.sort(mesh.vertices[mesh.faces[t]].round(12).view("f8,f8,f8").ravel())
    ours_p, theirs_p = ours.prim[both], theirs_prim[both]
    differ = [i for i in np.nonzero(ours_p != theirs_p)[0] if not np.array_equal(corners(ours_p[i]), corners(theirs_p[i]))]
    assert len(differ) <= 0.001 * both.sum(), f"{len(differ)} of {both.sum()} hits on other triangles"
    for i in differ:
        shared = set(map(tuple, mesh.vertices[mesh.faces[ours_p[i]]])) & set(map(tuple, mesh.vertices[mesh.faces[theirs_p[i]]]))
        assert shared, f"ray {i}: triangles {ours_p[i]} and {theirs_p[i]} share no corner"
    np.testing.assert_allclose(ours.t[both], theirs_t[both], rtol=1e-5)
