"""Baking from Python: what `gridrt bake` does, its summary as a dict, its refusals as
exceptions."""

import os
import pathlib

import pytest

import gridrt

MESHES = pathlib.Path(__file__).resolve().parents[4] / "shared" / "meshes"


def reference():
    path = MESHES / "dragon_res4.ply"
    if not path.is_file():
        if os.environ.get("CI"):
            raise FileNotFoundError(path)
        pytest.skip("the shared meshes are not beside the project")
    return path


def test_a_bake_within_a_budget_is_written_and_traced(tmp_path):
    out = tmp_path / "dragon.gltf"
    summary = gridrt.bake(reference(), out, max_bytes=0.5, samples=20_000)
    assert out.is_file() and summary["output"] == str(out)
    assert summary["grid_bytes"] <= 0.5 * summary["micro_triangles"] or not summary["compression"]["budget_met"]
    assert summary["symmetric"]["rms"] > 0
    assert isinstance(summary["warnings"], list) and isinstance(summary["notes"], list)
    scene = gridrt.load(out, backend="cpu")
    hits = scene.intersect(*scene.camera_rays(32, 24))
    assert (hits.prim >= 0).any()
    # The micro-triangles hit number within their base triangle at the micro-mesh's level.
    found = hits.prim >= 0
    assert hits.micro[found].max() < 4 ** summary["levels"]
    # An input is never written over.
    written = out.read_bytes()
    with pytest.raises(gridrt.GridrtError) as caught:
        gridrt.bake(out, out, samples=20_000)
    assert str(out) in str(caught.value) and "\n" not in str(caught.value)
    assert out.read_bytes() == written


def test_bakes_refuse_what_the_cli_refuses(tmp_path):
    ref = reference()
    with pytest.raises(gridrt.GridrtError, match="cannot be asked for together"):
        gridrt.bake(ref, tmp_path / "a.gltf", max_error=1e-3, max_bytes=1.0)
    with pytest.raises(gridrt.GridrtError, match="at most 6"):
        gridrt.bake(ref, tmp_path / "a.gltf", levels=7)
    with pytest.raises(gridrt.GridrtError, match="missing.ply"):
        gridrt.bake(tmp_path / "missing.ply", tmp_path / "a.gltf")
    assert not (tmp_path / "a.gltf").exists()
    assert list(tmp_path.iterdir()) == []
