"""gridrt: ray tracing of micro-meshes (triangular grid primitives) on any GPU or the CPU.

    import numpy as np, gridrt
    scene = gridrt.load("bunny.obj", levels=3)      # or gridrt.Scene.from_arrays(v, f)
    hits = scene.intersect(origins, directions)     # (N, 3) float arrays in, arrays out
    image = scene.render(640, 480, shading="lit")   # (480, 640, 4) uint8
    gridrt.bake("scan.ply", "scan.gltf", max_bytes=0.5)  # a displaced micro-mesh, as `gridrt bake`

Many views across a Dask cluster: ``gridrt.views``. Rays, cameras and distances are in the mesh file's units. Tracing runs with the GIL
released, on the GPU when there is one (``backend="auto"``) or on the CPU.
"""

from ._gridrt import GridrtError, Hits, Scene, bake, load, write_png

__all__ = ["GridrtError", "Hits", "Scene", "bake", "load", "write_png"]
