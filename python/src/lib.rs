//! `tstat._tstat`: the native half of the Python package. It holds no logic of its own:
//! commands are the command line's (`tstat::cli::api`), renders the library's job
//! (`tstat::job::render`), bundles the library's reader. What it adds is the bridge:
//! NumPy arrays (moved, not copied, out of the arrays Rust built), the GIL released
//! while Rust works, progress handed to a Python callable, Ctrl-C turned into a clean
//! stop, and errors raised as `tstat.TstatError` with the command line's message.

use numpy::{IntoPyArray, PyArray4};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tstat::job::{Progress, Stage};

pyo3::create_exception!(
    tstat,
    TstatError,
    PyValueError,
    "Bad input or a failed job; the message is the command line's."
);

/// The command line's one-line message for `e`, without its `error: ` prefix.
fn to_py(e: anyhow::Error) -> PyErr {
    let line = tstat::cli::error_line(&e);
    TstatError::new_err(line.trim_start_matches("error: ").to_string())
}

/// Runs a command in-process, as `tstat ARGV...` would, with the GIL released.
#[pyfunction]
fn run(py: Python<'_>, argv: Vec<String>) -> PyResult<()> {
    py.detach(|| tstat::cli::api::run_command(&argv))
        .map_err(to_py)
}

/// A render's progress as the Python side polls it.
#[derive(Default)]
struct Shared {
    cancel: AtomicBool,
    stage: Mutex<Option<(Stage, u64)>>,
    done: AtomicU64,
    status: Mutex<String>,
    /// Stages over but not yet handed to the callback (a short pilot can start and
    /// end between two polls): stage, total, last status.
    ended: Mutex<Vec<(Stage, u64, String)>>,
    notes: Mutex<Vec<String>>,
}

impl Progress for Shared {
    fn start(&self, stage: Stage, total: u64) {
        *self.stage.lock().unwrap_or_else(PoisonError::into_inner) = Some((stage, total));
        self.done.store(0, Ordering::Relaxed);
        self.status
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
    }
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }
    fn status(&self, text: &str) {
        *self.status.lock().unwrap_or_else(PoisonError::into_inner) = text.to_string();
    }
    fn finish(&self) {
        let stage = self
            .stage
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some((stage, total)) = stage {
            let status = self
                .status
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone();
            self.ended
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .push((stage, total, status));
        }
    }
    fn note(&self, line: &str) {
        self.notes
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(line.to_string());
    }
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

impl Shared {
    /// Hands the stages that ended since the last call (done = total), then the
    /// current stage, its paths done and total, and the status to `callback`.
    fn report(&self, py: Python<'_>, callback: &Py<PyAny>) -> PyResult<()> {
        let ended = std::mem::take(&mut *self.ended.lock().unwrap_or_else(PoisonError::into_inner));
        for (stage, total, status) in ended {
            callback.call1(py, (stage.name(), total, total, status))?;
        }
        let stage = *self.stage.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((stage, total)) = stage {
            let done = self.done.load(Ordering::Relaxed).min(total);
            let status = self
                .status
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .clone();
            callback.call1(py, (stage.name(), done, total, status))?;
        }
        Ok(())
    }
}

/// Renders the job of a `render SCENE --out DIR ...` command line. The render runs on
/// its own threads; this thread wakes ten times a second (without the GIL between) to
/// hand progress to `progress(stage, done, total, status)` and to look for Ctrl-C,
/// which stops the render after the rows under way and raises KeyboardInterrupt with
/// nothing written. Returns the notes the job made (what `tstat render` prints).
#[pyfunction]
#[pyo3(signature = (argv, progress=None))]
fn render(py: Python<'_>, argv: Vec<String>, progress: Option<Py<PyAny>>) -> PyResult<Vec<String>> {
    let (scene, job) = py
        .detach(|| tstat::cli::api::render_job(&argv))
        .map_err(to_py)?;
    let shared = Arc::new(Shared::default());
    let worker = {
        let shared = shared.clone();
        std::thread::spawn(move || tstat::job::render(scene, &job, &*shared))
    };
    let mut interrupted = None;
    while !worker.is_finished() {
        py.detach(|| {
            for _ in 0..10 {
                if worker.is_finished() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        });
        let polled = py.check_signals().and_then(|()| match &progress {
            Some(cb) => shared.report(py, cb),
            None => Ok(()),
        });
        if let Err(e) = polled {
            // Ctrl-C, or the callback raised: stop the render and raise that.
            shared.cancel.store(true, Ordering::Relaxed);
            interrupted = Some(e);
            break;
        }
    }
    let result = py.detach(|| worker.join());
    if let Some(e) = interrupted {
        return Err(e);
    }
    match result {
        Ok(Ok(_)) => {
            if let Some(cb) = &progress {
                shared.report(py, cb)?;
            }
            Ok(std::mem::take(
                &mut *shared.notes.lock().unwrap_or_else(PoisonError::into_inner),
            ))
        }
        Ok(Err(e)) => Err(to_py(e)),
        Err(_) => Err(TstatError::new_err(
            "the render stopped on an internal error",
        )),
    }
}

/// A statistics bundle on disk, opened and checked (`tstat::bundle::Bundle`). Arrays
/// are read when asked, each a new NumPy array owned by Python.
#[pyclass(module = "tstat._tstat", frozen)]
struct Bundle {
    inner: tstat::bundle::Bundle,
    /// A folder this object owns and removes when it is dropped (renders and merges
    /// made without `out`).
    owned: Option<PathBuf>,
}

impl Drop for Bundle {
    fn drop(&mut self) {
        if let Some(dir) = &self.owned {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// An f32 (H, W, T, C) volume handed to Python.
type Volume<'py> = Bound<'py, PyArray4<f32>>;

fn bundle_error(e: tstat::bundle::BundleError) -> PyErr {
    to_py(e.into())
}

#[pymethods]
impl Bundle {
    /// Opens the bundle at `path`; with `owned`, the folder `owned` (which holds it) is
    /// removed when this object is dropped.
    #[new]
    #[pyo3(signature = (path, owned=None))]
    fn new(py: Python<'_>, path: PathBuf, owned: Option<PathBuf>) -> PyResult<Self> {
        let inner = py
            .detach(|| tstat::bundle::Bundle::open(&path))
            .map_err(|e| {
                if let Some(d) = &owned {
                    let _ = std::fs::remove_dir_all(d);
                }
                bundle_error(e)
            })?;
        Ok(Bundle { inner, owned })
    }

    /// The bundle's folder.
    #[getter]
    fn path(&self) -> PathBuf {
        self.inner.dir.clone()
    }

    /// Whether the folder is removed when this object is dropped.
    #[getter]
    fn temporary(&self) -> bool {
        self.owned.is_some()
    }

    /// `manifest.json` as text.
    fn manifest_json(&self) -> PyResult<String> {
        tstat::bundle::read::manifest_json(&self.inner.manifest)
            .map_err(|p| TstatError::new_err(p.to_string()))
    }

    /// The noisy mean S / n, f32 (H, W, T, C): the array `tstat export --out` writes.
    fn mean<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray4<f32>>> {
        let a = py
            .detach(|| self.inner.noisy_mean())
            .map_err(bundle_error)?;
        Ok(a.into_pyarray(py))
    }

    /// SPEC 5's skewness-corrected mean theta and the variance of the estimate
    /// V = sigma2 / n, each f32 (H, W, T, C), in the transform's domain.
    fn estimates<'py>(&self, py: Python<'py>) -> PyResult<(Volume<'py>, Volume<'py>)> {
        let e = py.detach(|| self.inner.estimates()).map_err(bundle_error)?;
        Ok((e.theta.into_pyarray(py), e.variance.into_pyarray(py)))
    }

    /// Paths that deposited something in each voxel, u32 (H, W, T).
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let a = py.detach(|| self.inner.nonzero()).map_err(bundle_error)?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// Samples of each pixel, u32 (H, W) (every pixel `spp` unless adaptive).
    fn pixel_spp<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = &self.inner.manifest;
        let n: Vec<u32> = (0..m.height * m.width)
            .map(|p| self.inner.samples(p) as u32)
            .collect();
        let a = ndarray::Array2::from_shape_vec((m.height, m.width), n)
            .map_err(|e| TstatError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// The G-buffers: albedo (H, W, 3), normal (H, W, 3), depth (H, W), emitter
    /// (H, W), and medium (H, W) for scenes with media; f32.
    fn gbuffers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let b = &self.inner;
        let (albedo, normal, depth, emitter, medium) = py
            .detach(|| -> Result<_, tstat::bundle::BundleError> {
                Ok((
                    b.albedo()?,
                    b.normal()?,
                    b.depth()?,
                    b.emitter()?,
                    b.medium()?,
                ))
            })
            .map_err(bundle_error)?;
        let d = PyDict::new(py);
        d.set_item("albedo", albedo.into_pyarray(py))?;
        d.set_item("normal", normal.into_pyarray(py))?;
        d.set_item("depth", depth.into_pyarray(py))?;
        d.set_item("emitter", emitter.into_pyarray(py))?;
        if let Some(m) = medium {
            d.set_item("medium", m.into_pyarray(py))?;
        }
        Ok(d)
    }

    /// The steady-state mean radiance, f64 (H, W, C).
    fn steady<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let a = py.detach(|| self.inner.steady()).map_err(bundle_error)?;
        Ok(a.into_pyarray(py).into_any())
    }
}

#[pymodule]
fn _tstat(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TstatError", m.py().get_type::<TstatError>())?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_class::<Bundle>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
