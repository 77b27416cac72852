"""gridrt from Python beside what users have, and many views across Dask workers.

    python host/python/benches/bench.py rays MESH... [--rays N] [--levels L]
    python host/python/benches/bench.py views BAKED.gltf [--views 36] [--size 320x240]

`rays`: closest hits of N random rays (from a sphere around the mesh towards points inside
its box) per second from Python, best of three after a warm-up: Embree (trimesh + embreex)
and gridrt on the file's triangles, then on the micro-triangles of L levels of Loop
subdivision (Embree given them as `gridrt export` writes them; gridrt as grids and as its
triangle baseline). Memory: gridrt's structure (its own count), and for both the growth of a
fresh process's resident memory while the tracer loads, builds and traces a first ray (Embree
does not tell its size; gridrt's includes loading and subdividing the mesh).

`views`: a turntable rendered through `gridrt.views.render_views` on a Dask LocalCluster of
1 and then 2 workers (one thread each, the CPU backend on one thread each): seconds, and
whether the images are the same.
"""

import argparse
import multiprocessing
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

import gridrt

ROOT = pathlib.Path(__file__).resolve().parents[3]
GRIDRT = ROOT / "target" / "release" / "gridrt"


def resident_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def rays_through(lo, hi, count, seed=1):
    rng = np.random.default_rng(seed)
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo)
    away = rng.normal(size=(count, 3))
    origins = centre + radius * away / np.linalg.norm(away, axis=1, keepdims=True)
    targets = lo + rng.random((count, 3)) * (hi - lo)
    return origins, targets - origins


def best_rate(trace, rays):
    trace()
    seconds = []
    for _ in range(3):
        start = time.perf_counter()
        trace()
        seconds.append(time.perf_counter() - start)
    return rays / min(seconds)


def embree_row(path, origins, directions):
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    mesh = trimesh.load(path, process=False, force="mesh")
    before = resident_bytes()
    intersector = RayMeshIntersector(mesh)
    intersector.intersects_first(origins[:1], directions[:1])
    grown = resident_bytes() - before
    rate = best_rate(lambda: intersector.intersects_first(origins, directions), len(origins))
    return len(mesh.faces), rate, "", grown, "CPU"


def gridrt_row(path, origins, directions, **options):
    before = resident_bytes()
    scene = gridrt.load(path, **options)
    scene.intersect(origins[:1], directions[:1])
    grown = resident_bytes() - before
    rate = best_rate(lambda: scene.intersect(origins, directions), len(origins))
    return None, rate, f"{scene.memory / 1e6:.1f} MB", grown, scene.device


def isolated(row, *args, **kwargs):
    """`row` in a process of its own, so that its memory growth is its own."""
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        return pool.apply(row, args, kwargs)


def rays(args):
    print("| mesh | micro-triangles | tracer | rays/s | structure | RSS growth | device |")
    print("|---|---:|---|---:|---:|---:|---|")
    for path in args.meshes:
        lo, hi = np.array(gridrt.load(path, levels=0, backend="cpu").bounds)
        origins, directions = rays_through(lo, hi, args.rays)
        name = pathlib.Path(path).name
        with tempfile.TemporaryDirectory() as tmp:
            micro = pathlib.Path(tmp) / "micro.ply"
            subprocess.run([GRIDRT, "-q", "export", path, "--levels", str(args.levels), "-o", micro], check=True)
            for levels, file in ((0, path), (args.levels, micro)):
                count, rate, structure, grown, device = isolated(embree_row, file, origins, directions)
                print(f"| {name} | {count:,} | Embree (embreex) | {rate:,.0f} | | {grown / 1e6:.1f} MB | {device} |")
                modes = ["triangles"] if levels == 0 else ["grid", "triangles"]
                for mode in modes:
                    for backend in args.backends:
                        _, rate, structure, grown, device = isolated(
                            gridrt_row, path, origins, directions, levels=levels, mode=mode, backend=backend
                        )
                        tracer = f"gridrt {'grids' if mode == 'grid' else 'triangles'} L={levels} ({backend})"
                        print(f"| {name} | {count:,} | {tracer} | {rate:,.0f} | {structure} | {grown / 1e6:.1f} MB | {device} |")
        sys.stdout.flush()


def views(args):
    from distributed import Client, LocalCluster

    from gridrt.views import render_views, turntable

    width, height = map(int, args.size.split("x"))
    cameras = turntable(args.views)
    results = {}
    for workers in (1, 2):
        with LocalCluster(
            n_workers=workers, threads_per_worker=1, dashboard_address=None, env={"RAYON_NUM_THREADS": "1"}
        ) as cluster, Client(cluster) as client:
            # The workers load the scene once each before the timed run.
            render_views(client, args.baked, cameras[:workers * 2], width=8, height=8, backend="cpu")
            start = time.perf_counter()
            images = render_views(client, args.baked, cameras, width=width, height=height, backend="cpu")
            results[workers] = (time.perf_counter() - start, images)
    same = all(np.array_equal(a, b) for a, b in zip(results[1][1], results[2][1]))
    one, two = results[1][0], results[2][0]
    print(f"{args.views} views {width}x{height}: 1 worker {one:.2f} s, 2 workers {two:.2f} s, "
          f"speed-up {one / two:.2f}x, same images: {same}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("rays")
    r.add_argument("meshes", nargs="+")
    r.add_argument("--rays", type=int, default=200_000)
    r.add_argument("--levels", type=int, default=3)
    r.add_argument("--backends", nargs="+", default=["cpu"])
    v = sub.add_parser("views")
    v.add_argument("baked")
    v.add_argument("--views", type=int, default=36)
    v.add_argument("--size", default="320x240")
    args = parser.parse_args()
    {"rays": rays, "views": views}[args.command](args)


if __name__ == "__main__":
    main()
