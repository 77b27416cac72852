"""Many views of a scene rendered as tasks on a Dask cluster.

Each view is one task. A worker loads the scene the first time one of its tasks needs it and
keeps it for the next ones, so each worker loads it once however many views it renders; the
images come back as arrays, or are written as PNG files by the workers.

    from dask.distributed import Client
    import gridrt
    from gridrt.views import render_views, turntable

    client = Client("tcp://scheduler:8786")      # or Client(LocalCluster(n_workers=2))
    images = render_views(client, "scan.gltf", turntable(36), width=640, height=480)

The scene file must be readable at the same path on every worker.
"""

import os
from typing import Any, Dict, List, Optional, Sequence

from ._gridrt import Scene, load, write_png

__all__ = ["render_views", "turntable"]

# The scenes this process has loaded, by what they were loaded from: a worker's tasks share
# them.
_SCENES: Dict[Any, Scene] = {}


def turntable(views: int, *, azimuth: float = 35.0, elevation: float = 25.0, **camera: Any) -> List[Dict[str, Any]]:
    """`views` cameras around the mesh at equal steps of azimuth, the first at `azimuth`; any
    other camera option (target, distance, fov, up) is the same for every view."""
    if views < 1:
        raise ValueError(f"a turntable of {views} views: at least one")
    return [dict(camera, azimuth=azimuth + 360.0 * k / views, elevation=elevation) for k in range(views)]


def _scene(path: Optional[str], options: Dict[str, Any]) -> Scene:
    key = (path, tuple(sorted(options.items())))
    if key not in _SCENES:
        _SCENES[key] = load(path, **options)
    return _SCENES[key]


def _render(view: int, camera: Dict[str, Any], path, options, width, height, render, output) -> Any:
    image = _scene(path, options).render(width, height, camera=camera, **render)
    if output is None:
        return image
    file = output.format(view)
    write_png(file, image)
    return file


def render_views(
    client: Any,
    path: Optional[str],
    cameras: Sequence[Dict[str, Any]],
    *,
    width: int = 640,
    height: int = 480,
    shading: str = "eye",
    ao_samples: int = 16,
    output: Optional[str] = None,
    **load_options: Any,
) -> List[Any]:
    """Renders `path` (a file every worker can read; None: the built-in scene) from each of
    `cameras` (dicts of the camera options of `Scene.render`) on the workers of the Dask
    `client`, a task per view. `load_options` are `gridrt.load`'s (levels, mode, backend, ...).

    Returns the images in the order of `cameras`: (height, width, 4) uint8 arrays, or with
    `output` (a pattern such as "frames/view_{:03d}.png", filled with the view's number) the
    paths of the PNG files the workers wrote."""
    path = None if path is None else os.fspath(path)
    render = {"shading": shading, "ao_samples": ao_samples}
    futures = [
        client.submit(_render, k, dict(camera), path, load_options, width, height, render, output, pure=False)
        for k, camera in enumerate(cameras)
    ]
    return client.gather(futures)
