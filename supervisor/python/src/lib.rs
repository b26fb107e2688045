//! `harvemu._harvemu`: the emulated harvester for Python, with a program in place of some of its
//! nodes (see `supervisor::session`). The Python package's `harvemu.bus` builds the python-can
//! interface on it.
//!
//! Contract: every call that runs the harvester releases the GIL while it runs, so other Python
//! threads go on; a session is used from any thread. In virtual time, calls from two threads are
//! served in turn; paced by the wall clock, the bus runs between calls, and a `recv` waiting in
//! one thread does not hold up a `send` from another. Bad input (a config with problems, a frame that cannot be) raises
//! `ValueError` with harvemu's message, naming file and line where there are some; a failure of
//! harvemu itself raises `RuntimeError`.

use bus::{Frame, Id, extended_id, standard_id};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::sync::RwLock;
use supervisor::session::{Delivered, ErrorFrames, FOREVER_S, Filter, Options, Session};

/// Bus time a `recv` runs between looks at Python's signals, s: in virtual time, and paced by
/// the wall clock (where it is also how long a `close` may wait for a `recv` in another thread).
const STEP_S: f64 = 1.0;
const PACED_STEP_S: f64 = 0.1;

fn error(e: supervisor::Error) -> PyErr {
    let message = e.report().to_string();
    match e {
        supervisor::Error::BadInput(_) | supervisor::Error::Config(_) | supervisor::Error::Plant(_) => {
            PyValueError::new_err(message)
        }
        _ => PyRuntimeError::new_err(message),
    }
}

/// A frame as `recv` hands it over: bus time (s), identifier, extended, remote, DLC, data,
/// whether the program's own controller sent it, and for an error frame the controller that
/// reports it (the identifier is then SocketCAN's `can_id`, `CAN_ERR_FLAG` and classes).
type Message<'py> = (
    f64,
    u32,
    bool,
    bool,
    u8,
    Bound<'py, PyBytes>,
    bool,
    Option<String>,
);

/// What reached the program, as `recv` hands it over.
fn message(py: Python<'_>, d: Delivered) -> Message<'_> {
    match d {
        Delivered::Frame(r) => {
            let f = r.frame;
            let data = PyBytes::new(py, f.data());
            (
                r.at_s,
                f.raw_id(),
                f.is_extended(),
                f.is_remote(),
                f.dlc(),
                data,
                r.own,
                None,
            )
        }
        Delivered::Error(e) => {
            let data = PyBytes::new(py, &e.data);
            (e.at_s, e.can_id, false, false, 8, data, false, Some(e.controller))
        }
    }
}

/// A frame from its parts, as python-can's `Message` has them.
fn frame(
    arbitration_id: u32,
    data: &[u8],
    extended: bool,
    remote: bool,
    dlc: Option<usize>,
) -> PyResult<Frame> {
    let id: Id = if extended {
        extended_id(arbitration_id).map(Into::into)
    } else {
        u16::try_from(arbitration_id)
            .map_err(|_| bus::Error::IdOutOfRange {
                raw: arbitration_id,
                bits: 11,
            })
            .and_then(standard_id)
            .map(Into::into)
    }
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let frame = if remote {
        Frame::new_remote(id, dlc.unwrap_or(data.len()))
    } else {
        Frame::new_data(id, data)
    }
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(frame)
}

/// A frame's parts: identifier, data, extended, remote, DLC.
type Parts = (u32, Vec<u8>, bool, bool, Option<usize>);

fn frames(parts: Vec<Parts>) -> PyResult<Vec<Frame>> {
    parts
        .into_iter()
        .map(|(id, data, extended, remote, dlc)| frame(id, &data, extended, remote, dlc))
        .collect()
}

/// A harvester with a program on its bus.
#[pyclass(module = "harvemu._harvemu", frozen)]
struct Harvester {
    session: RwLock<Option<Session>>,
    paced: bool,
}

impl Harvester {
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&Session) -> supervisor::Result<T> + Send,
    ) -> PyResult<T> {
        py.allow_threads(|| {
            let guard = self
                .session
                .read()
                .map_err(|_| PyRuntimeError::new_err("the session broke in another thread"))?;
            let session = guard
                .as_ref()
                .ok_or_else(|| PyValueError::new_err("the harvester is closed"))?;
            f(session).map_err(error)
        })
    }
}

#[pymethods]
impl Harvester {
    /// Starts the harvester of `config` (the built-in default when None) without the nodes in
    /// `without`, with the program on its bus as `name`; in virtual time, or paced by the wall
    /// clock when `virtual_time` is False. `start_time` (RFC 3339 or seconds since 1970, as
    /// `--start-time`) is where bus time zero lies; `own_frames`: the program receives its own
    /// frames.
    #[new]
    #[pyo3(signature = (config=None, without=Vec::new(), seed=None, name=String::from("program"), virtual_time=true, start_time=None, own_frames=false, error_frames="own"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        config: Option<std::path::PathBuf>,
        without: Vec<String>,
        seed: Option<u64>,
        name: String,
        virtual_time: bool,
        start_time: Option<String>,
        own_frames: bool,
        error_frames: &str,
    ) -> PyResult<Harvester> {
        let error_frames = match error_frames {
            "own" => ErrorFrames::Own,
            "all" => ErrorFrames::All,
            "none" => ErrorFrames::None,
            other => {
                return Err(PyValueError::new_err(format!(
                    "error_frames={other:?}: give \"own\" (the program's controller's), \"all\" or \"none\""
                )));
            }
        };
        let start_time = start_time
            .map(|t| bus::time::Epoch::parse(&t))
            .transpose()
            .map_err(|e| PyValueError::new_err(format!("start_time: {e}")))?;
        let options = Options {
            config,
            without,
            seed,
            name,
            paced: !virtual_time,
            start_time,
            own_frames,
            error_frames,
        };
        let session = py.allow_threads(|| Session::start(&options)).map_err(error)?;
        Ok(Harvester {
            session: RwLock::new(Some(session)),
            paced: !virtual_time,
        })
    }

    /// Whether bus time is virtual (False: paced by the wall clock).
    #[getter]
    fn virtual_time(&self) -> bool {
        !self.paced
    }

    /// When bus time zero is, in seconds since 1970: the wall clock at the start when paced,
    /// 2024-01-01T00:00:00Z in virtual time.
    fn epoch(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |s| Ok(s.epoch_s()))
    }

    /// Sets the program's filters: (can_id, can_mask, extended or None) each.
    fn set_filters(&self, py: Python<'_>, filters: Vec<(u32, u32, Option<bool>)>) -> PyResult<()> {
        let filters: Vec<Filter> = filters
            .into_iter()
            .map(|(id, mask, extended)| Filter { id, mask, extended })
            .collect();
        self.with(py, move |s| s.set_filters(&filters))
    }

    /// The next frame or error frame for the program within `timeout` s of bus time (None: no
    /// limit).
    #[pyo3(signature = (timeout=None))]
    fn recv<'py>(&self, py: Python<'py>, timeout: Option<f64>) -> PyResult<Option<Message<'py>>> {
        let mut left = timeout.unwrap_or(FOREVER_S);
        if !(left.is_finite() && left >= 0.0) {
            return Err(PyValueError::new_err(format!("timeout {left} s is not a time")));
        }
        // A second of bus time at a time, with Python's signals looked at in between: Ctrl-C
        // ends a recv that would wait long (a filter nothing passes, no timeout).
        let chunk = if self.paced { PACED_STEP_S } else { STEP_S };
        loop {
            let step = left.min(chunk);
            match self.with(py, move |s| s.recv(Some(step)))? {
                Some(Delivered::Frame(r)) => {
                    let f = r.frame;
                    let data = PyBytes::new(py, f.data());
                    let (id, ext, rtr, dlc) = (f.raw_id(), f.is_extended(), f.is_remote(), f.dlc());
                    return Ok(Some((r.at_s, id, ext, rtr, dlc, data, r.own, None)));
                }
                Some(Delivered::Error(e)) => {
                    let data = PyBytes::new(py, &e.data);
                    return Ok(Some((
                        e.at_s,
                        e.can_id,
                        false,
                        false,
                        8,
                        data,
                        false,
                        Some(e.controller),
                    )));
                }
                None => {}
            }
            left -= step;
            if left <= 0.0 {
                return Ok(None);
            }
            py.check_signals()?;
        }
    }

    /// In virtual time, the next slice of the bus (0.1 s): its end (bus time, s) and every frame
    /// and error frame for the program up to it, as `recv` gives each. The harvester computes the
    /// next slice while the caller works through this one; any other call is carried out at the
    /// end of the slice being computed.
    fn slice<'py>(&self, py: Python<'py>) -> PyResult<(f64, Vec<Message<'py>>)> {
        let (end, items) = self.with(py, |s| s.slice())?;
        Ok((end, items.into_iter().map(|d| message(py, d)).collect()))
    }

    /// Hands a frame to the program's controller; in virtual time, while its transmit queue is
    /// full, runs the bus until there is room or `timeout` s of bus time have passed (None: no
    /// limit). False when the frame was not queued.
    #[pyo3(signature = (arbitration_id, data, extended=true, remote=false, dlc=None, timeout=None))]
    #[allow(clippy::too_many_arguments)]
    fn send(
        &self,
        py: Python<'_>,
        arbitration_id: u32,
        data: Vec<u8>,
        extended: bool,
        remote: bool,
        dlc: Option<usize>,
        timeout: Option<f64>,
    ) -> PyResult<bool> {
        let frame = frame(arbitration_id, &data, extended, remote, dlc)?;
        let mut left = timeout.unwrap_or(FOREVER_S);
        if !(left.is_finite() && left >= 0.0) {
            return Err(PyValueError::new_err(format!("timeout {left} s is not a time")));
        }
        // As recv: a second of bus time at a time, Python's signals looked at in between.
        loop {
            let step = left.min(STEP_S);
            if self.with(py, move |s| s.send(frame, step))? {
                return Ok(true);
            }
            left -= step;
            if left <= 0.0 || self.paced {
                return Ok(false);
            }
            py.check_signals()?;
        }
    }

    /// The bus's bit rate, bit/s.
    fn bitrate(&self, py: Python<'_>) -> PyResult<u32> {
        self.with(py, |s| Ok(s.bitrate()))
    }

    /// Bus time by which every node on the bus has booted, s (before it, nodes may not yet
    /// acknowledge frames; in virtual time the first frame sent waits for it).
    fn ready_time(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |s| Ok(s.ready_s()))
    }

    /// Runs the harvester (paced: waits) until every node has booted; the bus time then, s.
    fn wait_ready(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |s| s.wait_ready())
    }

    /// Puts the program's controller in listen-only mode (True) or takes it out (False).
    fn set_listen_only(&self, py: Python<'_>, on: bool) -> PyResult<()> {
        self.with(py, move |s| s.set_listen_only(on))
    }

    /// The program's controller: (name, state, TEC, REC, listen-only), the state as in
    /// `states`.
    fn own(&self, py: Python<'_>) -> PyResult<(String, String, u16, u16, bool)> {
        let o = self.with(py, |s| s.own())?;
        Ok((
            o.state.name,
            o.state.state,
            o.state.tec,
            o.state.rec,
            o.listen_only,
        ))
    }

    /// Sends `frames` (identifier, data, extended, remote, DLC each) in turn, the first now, then
    /// one every `period` s of bus time, for `duration` s if given; the task's number.
    #[pyo3(signature = (frames, period, duration=None))]
    fn start_periodic(
        &self,
        py: Python<'_>,
        frames: Vec<Parts>,
        period: f64,
        duration: Option<f64>,
    ) -> PyResult<u64> {
        let frames = self::frames(frames)?;
        self.with(py, move |s| s.start_periodic(frames, period, duration))
    }

    /// Stops a periodic task; False when it had stopped already.
    fn stop_periodic(&self, py: Python<'_>, task: u64) -> PyResult<bool> {
        self.with(py, move |s| s.stop_periodic(task))
    }

    /// New frames for a periodic task from its next sending on; False when it has stopped.
    fn modify_periodic(&self, py: Python<'_>, task: u64, frames: Vec<Parts>) -> PyResult<bool> {
        let frames = self::frames(frames)?;
        self.with(py, move |s| s.modify_periodic(task, frames))
    }

    /// Every node's controller: (name, state, TEC, REC), the state "error active", "error
    /// passive" or "bus off".
    fn states(&self, py: Python<'_>) -> PyResult<Vec<(String, String, u16, u16)>> {
        let states = self.with(py, |s| s.states())?;
        Ok(states
            .into_iter()
            .map(|n| (n.name, n.state, n.tec, n.rec))
            .collect())
    }

    /// What the reference monitor shows, as JSON; None when it is left out.
    fn display(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.with(py, |s| s.display())
    }

    /// Sets a plant input ("operator.speed", "fault.door3_open", ...) from now on.
    fn set_input(&self, py: Python<'_>, input: String, value: f64) -> PyResult<()> {
        self.with(py, move |s| s.set_input(&input, value))
    }

    /// Carries out a scenario action written as in a scenario's timeline: `Disconnect("D3")`,
    /// `BitErrors(target: Node("D2"), hits: Always, until_s: Some(12.5))`, `Crash("B1")`, ...
    fn act(&self, py: Python<'_>, action: String) -> PyResult<()> {
        self.with(py, move |s| s.act(&action))
    }

    /// Checks expectations written as in a scenario's `expect` (one, or a list in brackets)
    /// against the run so far: a dict for each, with "expectation", "passed", "at_s" (when it
    /// was decided, or None) and "observed", as a scenario's report gives them.
    fn check<'py>(&self, py: Python<'py>, expectations: String) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let verdicts = self.with(py, move |s| s.check(&expectations))?;
        verdicts
            .into_iter()
            .map(|v| {
                let d = PyDict::new(py);
                d.set_item("expectation", v.expectation)?;
                d.set_item("passed", v.passed)?;
                d.set_item("at_s", v.at.map(|t| t.as_secs_f64()))?;
                d.set_item("observed", v.observed)?;
                Ok(d)
            })
            .collect()
    }

    /// Frames the program's controller has sent so far.
    fn sent(&self, py: Python<'_>) -> PyResult<u64> {
        self.with(py, |s| s.sent())
    }

    /// Runs the harvester for `seconds` of bus time; the bus time reached, s.
    fn run_for(&self, py: Python<'_>, seconds: f64) -> PyResult<f64> {
        self.with(py, move |s| s.run_for(seconds))
    }

    /// Bus time now, s.
    fn now(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |s| s.now())
    }

    /// Stops the harvester; later calls raise ValueError.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        // Without the GIL: a call in another thread may have to finish first.
        py.allow_threads(|| {
            let taken = self
                .session
                .write()
                .map_err(|_| PyRuntimeError::new_err("the session broke in another thread"))?
                .take();
            drop(taken);
            Ok(())
        })
    }
}

/// The module.
#[pymodule]
fn _harvemu(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Harvester>()?;
    Ok(())
}
