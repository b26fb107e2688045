//! The Python monitor's workload: `python -m harvemu.monitor SECONDS`, the six-sensor monitor
//! written in Python on the python-can interface (docs/PYTHON.md), in a process of its own with
//! the harvester in virtual time. Its speed includes the Python code: it is what a test engineer's
//! pytest run gets.

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

/// Runs the monitor with `python` for `seconds` of bus time.
pub fn measure(python: &str, seconds: f64) -> crate::Result<Monitor> {
    let cannot = |why: String| {
        crate::Error::BadInput(format!(
            "{python} -m harvemu.monitor: {why} (the row needs the Python package: \
             pip install supervisor/python; --python names the Python that has it)"
        ))
    };
    let out = Command::new(python)
        .args(["-m", "harvemu.monitor", &seconds.to_string()])
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| cannot(e.to_string()))?;
    if !out.status.success() {
        return Err(cannot(format!("it ended with {}", out.status)));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
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
