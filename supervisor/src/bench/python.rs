//! The Python rows, each run by the Python package in a process of its own with the harvester
//! in virtual time, so that their speed includes the Python code: what a test engineer's pytest
//! run gets.
//!
//! - python-monitor: `python -m harvemu.monitor SECONDS`, the six-sensor monitor written in
//!   Python on the python-can interface (docs/PYTHON.md).
//! - python-recv: `python -m harvemu.throughput FRAMES`, frames per second into a Python `recv`
//!   loop: python-can's own virtual bus (python-virtual), then harvemu's with the program's
//!   controller active (python-recv) and listen-only (python-recv-passive), in one run; each
//!   harvemu row with its ratio to python-virtual.

use serde::Serialize;
use std::process::{Command, Stdio};

/// What the monitor measured of itself.
#[derive(Serialize, Debug, Clone)]
pub struct Monitor {
    /// Always "python-monitor".
    pub scenario: &'static str,
    /// The Python that ran it.
    pub python: String,
    /// Bus time reached, s.
    pub virtual_seconds: f64,
    /// Wall-clock seconds from the bus's start to its end, in the monitor.
    pub wall_seconds: f64,
    /// Frames the monitor received.
    pub frames: u64,
    /// Wall-clock microseconds per received frame, Python included.
    pub us_per_frame: f64,
    /// Bus seconds per wall second.
    pub speedup: f64,
    /// SHA-256 of what it received (time, identifier, data): the same for the same seed.
    pub digest: String,
}

/// Runs `python -m MODULE ARG` and gives its standard output; a failure names the command and
/// what to install.
fn run_module(python: &str, module: &str, arg: &str) -> crate::Result<Vec<u8>> {
    let out = Command::new(python)
        .args(["-m", module, arg])
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| cannot(python, module, e.to_string()))?;
    if !out.status.success() {
        return Err(cannot(python, module, format!("it ended with {}", out.status)));
    }
    Ok(out.stdout)
}

fn cannot(python: &str, module: &str, why: String) -> crate::Error {
    crate::Error::BadInput(format!(
        "{python} -m {module}: {why} (the row needs the Python package: \
         pip install supervisor/python; --python names the Python that has it)"
    ))
}

/// Runs the monitor with `python` for `seconds` of bus time.
pub fn measure(python: &str, seconds: f64) -> crate::Result<Monitor> {
    let cannot = |why: String| cannot(python, "harvemu.monitor", why);
    let stdout = run_module(python, "harvemu.monitor", &seconds.to_string())?;
    let v: serde_json::Value = serde_json::from_slice(&stdout)
        .map_err(|e| cannot(format!("its output is not the monitor's JSON: {e}")))?;
    let number = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_f64)
            .ok_or_else(|| cannot(format!("its JSON has no number `{k}`")))
    };
    Ok(Monitor {
        scenario: "python-monitor",
        python: python.to_string(),
        virtual_seconds: number("bus_seconds")?,
        wall_seconds: number("wall_seconds")?,
        frames: number("frames")? as u64,
        us_per_frame: number("us_per_frame")?,
        speedup: number("speedup")?,
        digest: v
            .get("digest")
            .and_then(serde_json::Value::as_str)
            .ok_or_else(|| cannot("its JSON has no `digest`".into()))?
            .to_string(),
    })
}

/// One row of the recv loop's throughput.
#[derive(Serialize, Debug, Clone)]
pub struct Throughput {
    /// "python-virtual", "python-recv" or "python-recv-passive".
    pub scenario: String,
    /// The Python that ran it.
    pub python: String,
    /// Frames received.
    pub frames: u64,
    /// Wall-clock seconds of the loop.
    pub wall_seconds: f64,
    /// Frames per second into the loop.
    pub frames_per_second: f64,
    /// Frames per second over python-virtual's, measured in the same run (None for that row).
    pub ratio: Option<f64>,
}

impl Throughput {
    /// The row as a line of the bench's text output.
    pub fn line(&self) -> String {
        let ratio = self
            .ratio
            .map_or_else(String::new, |r| format!(", {r:.2} times python-virtual"));
        format!(
            "{}: {:.0} frames/s into a Python recv loop ({} frames in {:.2} s{ratio})",
            self.scenario, self.frames_per_second, self.frames, self.wall_seconds
        )
    }
}

/// Runs `python -m harvemu.throughput FRAMES`: python-virtual, python-recv and
/// python-recv-passive, each harvemu row with its ratio to python-virtual.
pub fn throughput(python: &str, frames: u64) -> crate::Result<Vec<Throughput>> {
    const MODULE: &str = "harvemu.throughput";
    let stdout = run_module(python, MODULE, &frames.to_string())?;
    let text = String::from_utf8_lossy(&stdout);
    let mut rows = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let v: serde_json::Value = serde_json::from_str(line)
            .map_err(|e| cannot(python, MODULE, format!("a line of its output is not JSON: {e}")))?;
        let number = |k: &str| {
            v.get(k)
                .and_then(serde_json::Value::as_f64)
                .ok_or_else(|| cannot(python, MODULE, format!("a row has no number `{k}`")))
        };
        let scenario = v
            .get("scenario")
            .and_then(serde_json::Value::as_str)
            .ok_or_else(|| cannot(python, MODULE, "a row has no `scenario`".into()))?;
        rows.push(Throughput {
            scenario: scenario.to_string(),
            python: python.to_string(),
            frames: number("frames")? as u64,
            wall_seconds: number("wall_seconds")?,
            frames_per_second: number("frames_per_second")?,
            ratio: None,
        });
    }
    let virtual_fps = rows
        .iter()
        .find(|r| r.scenario == "python-virtual")
        .map(|r| r.frames_per_second)
        .filter(|f| *f > 0.0)
        .ok_or_else(|| cannot(python, MODULE, "it gave no python-virtual row".into()))?;
    for r in rows.iter_mut().filter(|r| r.scenario != "python-virtual") {
        r.ratio = Some(r.frames_per_second / virtual_fps);
    }
    Ok(rows)
}
