//! The core is pure: none of its (normal) dependencies, direct or indirect, is an async runtime,
//! an actor framework or a socket crate. Read from `cargo metadata`, the resolved graph Cargo
//! itself builds from.

use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::process::Command;

/// Crates that would bring a clock, I/O or a scheduler into the core.
const FORBIDDEN: [&str; 9] = [
    "actix",
    "actix-rt",
    "tokio",
    "async-std",
    "smol",
    "mio",
    "socket2",
    "socketcan",
    "futures-util",
];

/// The names of every package `root` depends on at run time, through any path.
fn runtime_closure(metadata: &Value, root: &str) -> HashSet<String> {
    let packages: HashMap<&str, &str> = metadata["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["id"].as_str().unwrap(), p["name"].as_str().unwrap()))
        .collect();
    let nodes: HashMap<&str, &Value> = metadata["resolve"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["id"].as_str().unwrap(), n))
        .collect();
    let start = packages
        .iter()
        .find(|(_, name)| **name == root)
        .map(|(id, _)| *id)
        .expect("the package in the workspace");
    let (mut seen, mut todo) = (HashSet::new(), vec![start]);
    while let Some(id) = todo.pop() {
        if !seen.insert(id) {
            continue;
        }
        for dep in nodes[id]["deps"].as_array().unwrap() {
            // A normal dependency has kind null; dev and build dependencies are not in the crate.
            let normal = dep["dep_kinds"]
                .as_array()
                .unwrap()
                .iter()
                .any(|k| k["kind"].is_null());
            if normal {
                todo.push(dep["pkg"].as_str().unwrap());
            }
        }
    }
    seen.remove(start);
    seen.iter().map(|id| packages[id].to_string()).collect()
}

/// The platform the tests run on, as rustc names it (`x86_64-unknown-linux-gnu`).
fn host() -> String {
    let out = Command::new("rustc").arg("-vV").output().unwrap();
    assert!(
        out.status.success(),
        "rustc -vV: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let host = text.lines().find_map(|l| l.strip_prefix("host: "));
    host.unwrap_or_else(|| panic!("no host line in rustc -vV:\n{text}"))
        .to_string()
}

/// The dependency graph for this platform: offline, and only what this platform builds, so
/// that packages for other platforms need not be in cargo's cache.
fn metadata() -> Value {
    let host = host();
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--offline",
            "--filter-platform",
            &host,
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn the_core_depends_on_no_runtime_actor_or_socket_crate() {
    let metadata = metadata();
    let core = runtime_closure(&metadata, "bus");
    let bad: Vec<&str> = FORBIDDEN.iter().copied().filter(|c| core.contains(*c)).collect();
    assert!(bad.is_empty(), "the core pulls in {bad:?}");
    // The check sees what it is meant to: the runtime crate does pull them in.
    let runtime = runtime_closure(&metadata, "bus-runtime");
    for c in ["actix", "tokio", "socket2"] {
        assert!(runtime.contains(c), "bus-runtime without {c}?");
    }
    assert!(core.contains("crc"), "the walk found the core's own dependencies");
}
