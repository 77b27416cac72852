//! The Python module `gridrt._gridrt`, wrapped by the `gridrt` package (python/gridrt): a
//! scene loaded or built from arrays, closest hits of numpy rays, and rendered images, each
//! one call into the gridrt library with the GIL released. Arrays are checked here (shape,
//! dtype, finite numbers) so that nothing a caller passes reaches the library unchecked;
//! the library's errors become `gridrt.GridrtError` with the CLI's one-line message.
#![cfg(feature = "python")]

use std::path::PathBuf;
use std::sync::Mutex;

use gridrt::backend::{Backend, BackendChoice, Uploaded};
use gridrt::camera::{self, FileViewpoint};
use gridrt::grid::GridBuild;
use gridrt::input::{self, Input};
use gridrt::mesh::frame::LocalFrame;
use gridrt::mesh::Cleaning;
use gridrt::micromesh::bake::request::{bake_file, BakeRequest};
use gridrt::pipeline::{BuildOptions, RenderOptions, Representation, Shading};
use gridrt::progress::Progress;
use gridrt::rays::{self, SurfaceHit};
use gridrt::scene::Scene;
use gridrt::subdiv::Scheme;
use gridrt_shared::glam::{DVec3, Vec3};
use gridrt_shared::layout::{HitRecord, RayRecord, NO_HIT};
use gridrt_shared::ray::T_FAR;
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

create_exception!(
    _gridrt,
    GridrtError,
    PyException,
    "What gridrt refuses or fails at: a file it cannot read, options it cannot honour, a scene too large for the device. The message is the CLI's one line."
);

fn gridrt_error(e: gridrt::error::Error) -> PyErr {
    GridrtError::new_err(e.to_string())
}

/// A keyword argument the library refuses, as a `ValueError` naming it.
fn bad_option(name: &str, value: &str, e: gridrt::error::Error) -> PyErr {
    PyValueError::new_err(format!("{name}={value:?}: {e}"))
}

/// How a scene is built: the CLI's build options by their Python names.
struct Build {
    options: BuildOptions,
    backend: BackendChoice,
}

impl Build {
    fn parse(
        levels: u32,
        subdivision: &str,
        crease_angle: Option<f32>,
        mode: &str,
        lod: Option<u32>,
        backend: &str,
    ) -> PyResult<Build> {
        if levels > 6 {
            return Err(PyValueError::new_err(format!("levels={levels}: at most 6")));
        }
        let scheme: Scheme = subdivision
            .parse()
            .map_err(|e| bad_option("subdivision", subdivision, e))?;
        if let Some(angle) = crease_angle.filter(|a| !(0.0..=180.0).contains(a)) {
            return Err(PyValueError::new_err(format!(
                "crease_angle={angle}: between 0 and 180 degrees"
            )));
        }
        let representation: Representation = mode.parse().map_err(|e| bad_option("mode", mode, e))?;
        let backend: BackendChoice = backend.parse().map_err(|e| bad_option("backend", backend, e))?;
        let mut grid = GridBuild::new(levels);
        grid.scheme = scheme;
        grid.crease_angle = crease_angle;
        Ok(Build {
            options: BuildOptions {
                representation,
                grid,
                lod,
            },
            backend,
        })
    }
}

/// A scene ready to trace, in the local frame of its mesh (see `gridrt::mesh::frame`); rays
/// and cameras come in the file's units and are moved into it here.
#[pyclass(module = "gridrt", name = "Scene", frozen)]
struct PyScene {
    scene: Scene,
    /// The backend with the scene uploaded to it once, for every call after.
    device: Mutex<(Backend, Uploaded)>,
    frame: LocalFrame,
    /// The mesh's vertices, which cameras frame as the CLI frames them.
    positions: Vec<Vec3>,
    /// Micro-triangles per base triangle in the hits' numbering (1 for a micro-mesh traced
    /// as triangles, whose decoded triangles are numbered one by one).
    per_base: u32,
    /// The triangles loading dropped, so that hits name base triangles as the file numbers
    /// them.
    cleaning: Cleaning,
    name: String,
}

/// The closest hit of each ray, as arrays of one entry per ray.
#[pyclass(module = "gridrt", frozen, get_all)]
struct Hits {
    /// (N,) float32: distance along the ray in units of its direction's length; inf on a miss.
    t: Py<PyArray1<f32>>,
    /// (N,) int64: the base triangle, numbered as in the file (or the arrays); -1 on a miss.
    /// For a displaced micro-mesh traced as triangles, its decoded micro-triangle.
    prim: Py<PyArray1<i64>>,
    /// (N,) int64: the micro-triangle within the base triangle, in gridrt's numbering at the
    /// scene's depth; -1 on a miss.
    micro: Py<PyArray1<i64>>,
    /// (N,) float32: barycentrics of the hit, `(1 - u - v) a + u b + v c` for the
    /// micro-triangle's corners `a, b, c`.
    u: Py<PyArray1<f32>>,
    v: Py<PyArray1<f32>>,
    /// (N, 3) float32: the micro-triangle's unit geometric normal; zero on a miss.
    normal: Py<PyArray2<f32>>,
    /// How many rays.
    rays: usize,
}

#[pymethods]
impl Hits {
    fn __len__(&self) -> usize {
        self.rays
    }

    fn __repr__(&self) -> String {
        format!("<gridrt.Hits of {} rays>", self.rays)
    }
}

impl PyScene {
    fn build(py: Python<'_>, input: Input, build: Build) -> PyResult<PyScene> {
        let Build { options, backend } = build;
        py.detach(|| {
            let scene = Scene::from_input(&input, &options).map_err(|e| e.prefixed(&input.name))?;
            let backend = Backend::open(backend)?;
            let uploaded = backend.upload(&scene)?;
            let per_base = Scene::micro_triangles_per_base(&input, &options);
            Ok(PyScene {
                scene,
                device: Mutex::new((backend, uploaded)),
                frame: input.frame,
                positions: input.mesh.positions,
                per_base,
                cleaning: input.cleaning,
                name: input.name,
            })
        })
        .map_err(gridrt_error)
    }

    /// The backend and the scene's upload to it, one caller at a time.
    fn on_device(&self) -> std::sync::MutexGuard<'_, (Backend, Uploaded)> {
        self.device.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Rays in the local frame: origins moved, directions scaled alike, so that distances
    /// along them stay those of the file's units.
    fn local_rays(&self, rays: &Rays) -> Vec<RayRecord> {
        let t_max = &rays.t_max;
        (rays.origins.iter().zip(&rays.directions).enumerate())
            .map(|(i, (&o, &d))| RayRecord {
                origin: self.frame.to_local(DVec3::from(o)).to_array(),
                t_max: t_max[i.min(t_max.len() - 1)],
                dir: (DVec3::from(d) * self.frame.scale).as_vec3().to_array(),
                _pad: 0,
            })
            .collect()
    }

    /// The closest hit of each ray (distance and primitive), the GIL released.
    fn trace(&self, py: Python<'_>, rays: &[RayRecord]) -> PyResult<Vec<HitRecord>> {
        py.detach(|| {
            let device = self.on_device();
            device.0.trace_uploaded(&self.scene, &device.1, rays)
        })
        .map_err(|e| gridrt_error(e.prefixed(&self.name)))
    }

    fn camera(
        &self,
        width: u32,
        height: u32,
        camera: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<gridrt_shared::layout::Camera> {
        if width == 0 || height == 0 {
            return Err(PyValueError::new_err(format!("a {width}x{height} image has no pixels")));
        }
        let viewpoint = file_viewpoint(camera)?.local(&self.frame);
        camera::view_of(&self.positions, &viewpoint, width, height).map_err(gridrt_error)
    }
}

/// The rays of a call, in the file's units, checked.
struct Rays {
    origins: Vec<[f64; 3]>,
    directions: Vec<[f64; 3]>,
    /// One for every ray, or one per ray.
    t_max: Vec<f32>,
}

/// The rays of a call: origins, directions and each ray's `t_max`, checked.
fn checked_rays(
    origins: &Bound<'_, PyAny>,
    directions: &Bound<'_, PyAny>,
    t_max: Option<&Bound<'_, PyAny>>,
) -> PyResult<Rays> {
    let origins = points("origins", origins)?;
    let directions = points("directions", directions)?;
    if origins.len() != directions.len() {
        return Err(PyValueError::new_err(format!(
            "{} origins and {} directions: one of each per ray",
            origins.len(),
            directions.len()
        )));
    }
    if let Some(i) = directions.iter().position(|d| DVec3::from(*d) == DVec3::ZERO) {
        return Err(PyValueError::new_err(format!(
            "directions[{i}] is zero: a ray needs a direction"
        )));
    }
    let t_max = match t_max {
        None => vec![T_FAR],
        Some(t) => distances(t, origins.len())?,
    };
    Ok(Rays {
        origins,
        directions,
        t_max,
    })
}

/// An (N, 3) array of float32 or float64 as points, every number finite.
fn points(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; 3]>> {
    let rows: Vec<[f64; 3]> = if let Ok(a) = array.extract::<PyReadonlyArray2<'_, f64>>() {
        rows3(name, a.as_array().shape(), a.as_array().iter().copied())?
    } else if let Ok(a) = array.extract::<PyReadonlyArray2<'_, f32>>() {
        rows3(name, a.as_array().shape(), a.as_array().iter().map(|&x| x as f64))?
    } else {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a numpy array of shape (N, 3) and dtype float32 or float64, not {}",
            describe_array(array)
        )));
    };
    if let Some(i) = rows.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(PyValueError::new_err(format!(
            "{name}[{i}] is not finite: {:?}",
            rows[i]
        )));
    }
    Ok(rows)
}

fn rows3(name: &str, shape: &[usize], values: impl Iterator<Item = f64>) -> PyResult<Vec<[f64; 3]>> {
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (N, 3), not {shape:?}"
        )));
    }
    let flat: Vec<f64> = values.collect();
    Ok(flat.as_chunks::<3>().0.to_vec())
}

/// `t_max`: one number for every ray or one per ray, each above zero (infinity allowed).
fn distances(t: &Bound<'_, PyAny>, rays: usize) -> PyResult<Vec<f32>> {
    let values: Vec<f64> = if let Ok(x) = t.extract::<f64>() {
        vec![x]
    } else if let Ok(a) = t.extract::<PyReadonlyArray1<'_, f64>>() {
        a.as_array().to_vec()
    } else if let Ok(a) = t.extract::<PyReadonlyArray1<'_, f32>>() {
        a.as_array().iter().map(|&x| x as f64).collect()
    } else {
        return Err(PyTypeError::new_err(format!(
            "t_max must be a number or a float32/float64 array of shape (N,), not {}",
            describe_array(t)
        )));
    };
    if values.len() != 1 && values.len() != rays {
        return Err(PyValueError::new_err(format!(
            "t_max has {} values for {rays} rays: give one, or one per ray",
            values.len()
        )));
    }
    if let Some(i) = values.iter().position(|&x| x.is_nan() || x <= 0.0) {
        return Err(PyValueError::new_err(format!(
            "t_max[{i}] = {}: a distance above zero",
            values[i]
        )));
    }
    Ok(values.iter().map(|&x| (x as f32).min(T_FAR)).collect())
}

/// A 2-dimensional array of integers of type `T`: its shape and values; `None` for another
/// dtype or dimension.
fn integer_rows<T: numpy::Element + Copy + Into<i128>>(array: &Bound<'_, PyAny>) -> Option<(Vec<usize>, Vec<i128>)> {
    let a = array.extract::<PyReadonlyArray2<'_, T>>().ok()?;
    let a = a.as_array();
    Some((a.shape().to_vec(), a.iter().map(|&x| x.into()).collect()))
}

/// An (M, 3) array of integers as triangles of vertex indices below `vertices`.
fn faces(array: &Bound<'_, PyAny>, vertices: usize) -> PyResult<Vec<[u32; 3]>> {
    let Some((shape, values)) = (integer_rows::<i64>(array))
        .or_else(|| integer_rows::<i32>(array))
        .or_else(|| integer_rows::<u32>(array))
        .or_else(|| integer_rows::<u64>(array))
    else {
        return Err(PyTypeError::new_err(format!(
            "faces must be a numpy array of shape (M, 3) and an integer dtype, not {}",
            describe_array(array)
        )));
    };
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "faces must have shape (M, 3), not {shape:?}"
        )));
    }
    if let Some(i) = values.iter().position(|&x| x < 0 || x >= vertices as i128) {
        return Err(PyValueError::new_err(format!(
            "faces[{}] refers to vertex {} but there are {vertices} vertices",
            i / 3,
            values[i]
        )));
    }
    Ok((values.as_chunks::<3>().0.iter())
        .map(|c| c.map(|i| i as u32))
        .collect())
}

/// What a rejected argument is, for the message: an array's dtype and shape, or its type.
fn describe_array(value: &Bound<'_, PyAny>) -> String {
    let attribute = |name: &str| {
        value
            .getattr(name)
            .ok()
            .and_then(|a| a.str().ok())
            .map(|s| s.to_string())
    };
    match (attribute("dtype"), attribute("shape")) {
        (Some(dtype), Some(shape)) => format!("an array of dtype {dtype} and shape {shape}"),
        _ => format!(
            "a {}",
            value.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        ),
    }
}

/// The CLI's camera options by name (eye, target, up, fov, azimuth, elevation, distance), in
/// the file's units; what is left out is chosen as the CLI chooses it.
fn file_viewpoint(camera: Option<&Bound<'_, PyDict>>) -> PyResult<FileViewpoint> {
    let mut v = FileViewpoint::default();
    let Some(camera) = camera else {
        return Ok(v);
    };
    let point = |value: &Bound<'_, PyAny>, key: &str| -> PyResult<DVec3> {
        let p: [f64; 3] = value
            .extract()
            .map_err(|_| PyValueError::new_err(format!("camera[{key:?}] must be three numbers x, y, z")))?;
        Ok(DVec3::from(p))
    };
    for (key, value) in camera.iter() {
        let key: String = key.extract()?;
        let number = || -> PyResult<f64> {
            value
                .extract::<f64>()
                .map_err(|_| PyValueError::new_err(format!("camera[{key:?}] must be a number")))
        };
        match key.as_str() {
            "eye" => v.eye = Some(point(&value, &key)?),
            "target" => v.target = Some(point(&value, &key)?),
            "up" => v.up = point(&value, &key)?.as_vec3(),
            "fov" => v.fov_degrees = number()? as f32,
            "azimuth" => v.azimuth_degrees = number()? as f32,
            "elevation" => v.elevation_degrees = number()? as f32,
            "distance" => v.distance = Some(number()?),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "camera has no {key:?}: eye, target, up, fov, azimuth, elevation or distance"
                )))
            }
        }
    }
    Ok(v)
}

#[pymethods]
impl PyScene {
    /// Builds a scene from a mesh given as arrays: `vertices` (N, 3) float, `faces` (M, 3)
    /// integer indices into them; options as for `gridrt.load`.
    #[staticmethod]
    #[pyo3(signature = (vertices, faces, *, levels=3, subdivision="loop", crease_angle=None, mode="grid", lod=None, backend="auto"))]
    #[allow(clippy::too_many_arguments)] // Python keyword arguments
    fn from_arrays(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        levels: u32,
        subdivision: &str,
        crease_angle: Option<f32>,
        mode: &str,
        lod: Option<u32>,
        backend: &str,
    ) -> PyResult<PyScene> {
        let build = Build::parse(levels, subdivision, crease_angle, mode, lod, backend)?;
        let positions = points("vertices", vertices)?;
        let triangles = self::faces(faces, positions.len())?;
        let input = input::from_arrays("arrays", positions, triangles).map_err(gridrt_error)?;
        PyScene::build(py, input, build)
    }

    /// The closest hit of each ray: `Hits`, one entry per ray.
    #[pyo3(signature = (origins, directions, t_max=None))]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        t_max: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Hits> {
        let rays = self.local_rays(&checked_rays(origins, directions, t_max)?);
        let records = self.trace(py, &rays)?;
        let hits = py.detach(|| rays::surface_hits(&self.scene, &rays, &records));
        // The base triangle as the file numbers it, and the micro-triangle within it.
        let (prim, micro): (Vec<i64>, Vec<i64>) = (hits.iter())
            .map(|h| match h.triangle {
                NO_HIT => (-1, -1),
                t => (
                    self.cleaning.file_triangle(t / self.per_base) as i64,
                    (t % self.per_base) as i64,
                ),
            })
            .unzip();
        let column = |f: &dyn Fn(&SurfaceHit) -> f32| hits.iter().map(f).collect::<Vec<_>>().into_pyarray(py).unbind();
        let normals = Array2::from_shape_vec((hits.len(), 3), hits.iter().flat_map(|h| h.normal).collect())
            .expect("three per hit");
        Ok(Hits {
            t: column(&|h| h.t),
            prim: prim.into_pyarray(py).unbind(),
            micro: micro.into_pyarray(py).unbind(),
            u: column(&|h| h.u),
            v: column(&|h| h.v),
            normal: normals.into_pyarray(py).unbind(),
            rays: hits.len(),
        })
    }

    /// Whether anything lies along each ray before `t_max`.
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        t_max: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let rays = self.local_rays(&checked_rays(origins, directions, Some(t_max))?);
        let hits = self.trace(py, &rays)?;
        Ok(hits
            .iter()
            .map(|h| h.prim != NO_HIT)
            .collect::<Vec<_>>()
            .into_pyarray(py))
    }

    /// An image of the scene, (height, width, 4) uint8 RGBA; `shading` and `camera` as the
    /// CLI's `--shading` and camera options.
    #[pyo3(signature = (width=640, height=480, *, shading="eye", camera=None, ao_samples=16))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        shading: &str,
        camera: Option<&Bound<'py, PyDict>>,
        ao_samples: u32,
    ) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let shading: Shading = shading.parse().map_err(gridrt_error)?;
        let view = self.camera(width, height, camera)?;
        let options = RenderOptions {
            shading,
            ao_samples,
            ..RenderOptions::default()
        };
        let image = py
            .detach(|| {
                let device = self.on_device();
                (device.0).render_uploaded(&self.scene, &device.1, &view, &options, &|_| {})
            })
            .map_err(|e| gridrt_error(e.prefixed(&self.name)))?;
        let bytes = gridrt::image_io::rgba_bytes(&image.pixels);
        let array = Array3::from_shape_vec((height as usize, width as usize, 4), bytes).expect("four bytes a pixel");
        Ok(array.into_pyarray(py))
    }

    /// The primary ray of every pixel the camera sees, row by row from the top, in the file's
    /// units: `(origins, directions)`, each (height * width, 3) float64, for `intersect` (a
    /// depth or normal image).
    #[pyo3(signature = (width=640, height=480, *, camera=None))]
    fn camera_rays<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        camera: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let view = self.camera(width, height, camera)?;
        let rays = rays::view_rays(&view);
        let n = rays.len();
        let origins: Vec<f64> = (rays.iter())
            .flat_map(|r| self.frame.to_world(Vec3::from(r.origin)).to_array())
            .collect();
        let directions: Vec<f64> = (rays.iter())
            .flat_map(|r| (Vec3::from(r.dir).as_dvec3() / self.frame.scale).to_array())
            .collect();
        let as_array = |v: Vec<f64>| Array2::from_shape_vec((n, 3), v).expect("three per ray");
        let origins: Bound<'py, PyArray2<f64>> = as_array(origins).into_pyarray(py);
        let directions: Bound<'py, PyArray2<f64>> = as_array(directions).into_pyarray(py);
        PyTuple::new(py, [origins.into_any(), directions.into_any()])
    }

    /// Bytes of the scene's structure (what a device holds to trace it).
    #[getter]
    fn memory(&self) -> usize {
        self.scene.memory()
    }

    /// Where rays are traced: "cpu" or "gpu".
    #[getter]
    fn backend_kind(&self) -> &'static str {
        self.on_device().0.kind()
    }

    /// One line naming the device.
    #[getter]
    fn device(&self) -> String {
        self.on_device().0.describe()
    }

    /// The scene's box in the file's units: ((x, y, z) min, (x, y, z) max).
    #[getter]
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let b = self.scene.bounds();
        (
            self.frame.to_world(b.min).to_array(),
            self.frame.to_world(b.max).to_array(),
        )
    }

    fn __repr__(&self) -> String {
        format!("<gridrt.Scene {} on {}>", self.name, self.on_device().0.kind())
    }
}

/// Loads a mesh file (.obj, .ply, .gltf, .glb; a displaced micro-mesh as displaced grids) or,
/// with no path, the built-in scene, and builds it.
#[pyfunction]
#[pyo3(signature = (path=None, *, levels=3, subdivision="loop", crease_angle=None, mode="grid", lod=None, backend="auto"))]
#[allow(clippy::too_many_arguments)] // Python keyword arguments
fn load(
    py: Python<'_>,
    path: Option<PathBuf>,
    levels: u32,
    subdivision: &str,
    crease_angle: Option<f32>,
    mode: &str,
    lod: Option<u32>,
    backend: &str,
) -> PyResult<PyScene> {
    let build = Build::parse(levels, subdivision, crease_angle, mode, lod, backend)?;
    let input = py.detach(|| input::open(path.as_deref())).map_err(gridrt_error)?;
    PyScene::build(py, input, build)
}

/// Collects what a library call reports, for the dict it returns.
#[derive(Default)]
struct Collected {
    notes: Vec<String>,
    warnings: Vec<String>,
}

impl Progress for Collected {
    fn stage(&mut self, _name: &'static str, work: &mut dyn FnMut()) {
        work()
    }

    fn note(&mut self, line: &str) {
        self.notes.push(line.to_string());
    }

    fn warning(&mut self, line: &str) {
        self.warnings.push(line.to_string());
    }
}

/// Bakes the detailed mesh `reference` into a displaced micro-mesh written to `output` (glTF,
/// with its .bin and .bary beside it), as `gridrt bake` does with the same options; returns
/// the bake's summary (`gridrt bake --json`'s object) with its `notes` and `warnings`.
#[pyfunction]
#[pyo3(signature = (reference, output, *, levels=3, base=None, base_triangles=None, fit_rounds=None, compress_values=None, plain_values=false, max_bytes=None, max_error=None, within_bytes=None, nv_blocks=false, samples=1_000_000))]
#[allow(clippy::too_many_arguments)] // Python keyword arguments
fn bake<'py>(
    py: Python<'py>,
    reference: PathBuf,
    output: PathBuf,
    levels: u32,
    base: Option<PathBuf>,
    base_triangles: Option<usize>,
    fit_rounds: Option<u32>,
    compress_values: Option<f32>,
    plain_values: bool,
    max_bytes: Option<f64>,
    max_error: Option<f32>,
    within_bytes: Option<u64>,
    nv_blocks: bool,
    samples: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let defaults = BakeRequest::new(&reference, &output);
    let request = BakeRequest {
        base,
        base_triangles,
        levels,
        fit_rounds: fit_rounds.unwrap_or(defaults.fit_rounds),
        compress_values,
        plain_values,
        max_bytes,
        max_error,
        within_bytes,
        nv_blocks,
        samples,
        ..defaults
    };
    let mut collected = Collected::default();
    let summary = py
        .detach(|| bake_file(&request, &mut collected))
        .map_err(gridrt_error)?;
    let mut json = serde_json::to_value(&summary).map_err(|e| GridrtError::new_err(e.to_string()))?;
    collected.warnings.extend(summary.shortfalls);
    json["notes"] = collected.notes.into();
    json["warnings"] = collected.warnings.into();
    py.import("json")?.call_method1("loads", (json.to_string(),))
}

/// Writes an (height, width, 4) uint8 RGBA image as PNG (through a temporary file, so a
/// failure leaves no partial one).
#[pyfunction]
fn write_png(py: Python<'_>, path: PathBuf, image: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
    let array = image.as_array();
    let &[height, width, 4] = array.shape() else {
        return Err(PyValueError::new_err(format!(
            "image must have shape (height, width, 4), not {:?}",
            array.shape()
        )));
    };
    let bytes: Vec<u8> = array.iter().copied().collect();
    py.detach(|| gridrt::image_io::write_png_bytes(&path, &bytes, width as u32, height as u32))
        .map_err(gridrt_error)
}

#[pymodule]
fn _gridrt(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_class::<Hits>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(write_png, m)?)?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add("GridrtError", m.py().get_type::<GridrtError>())?;
    Ok(())
}
