//! The stated minimum Rust is true: every package of both workspaces (the main one and fuzz/)
//! declares a `rust-version` no lower than the highest `rust_version` of the locked packages it
//! builds on this platform, dev-dependencies included (`cargo test` builds them).
//!
//! Only one toolchain can be installed where the tests run, so the claim is checked against what
//! the dependencies declare rather than by building with the old compiler.

use serde_json::Value;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A Rust version as `rust-version` writes it, compared numerically ("1.88" == "1.88.0" <
/// "1.100").
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct RustVersion([u64; 3]);

impl RustVersion {
    fn parse(text: &str) -> RustVersion {
        let mut parts = [0; 3];
        let fields: Vec<&str> = text.split('.').collect();
        assert!((1..=3).contains(&fields.len()), "'{text}' is not a Rust version");
        for (part, field) in parts.iter_mut().zip(fields) {
            *part = field
                .parse()
                .unwrap_or_else(|_| panic!("'{text}' is not a Rust version"));
        }
        RustVersion(parts)
    }
}

impl std::fmt::Display for RustVersion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [major, minor, patch] = self.0;
        write!(f, "{major}.{minor}.{patch}")
    }
}

/// The platform the tests run on, as rustc names it (`x86_64-unknown-linux-gnu`).
fn host() -> String {
    let out = Command::new("rustc").arg("-vV").output().expect("run rustc -vV");
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("host: ").map(str::to_owned))
        .expect("rustc -vV names the host")
}

/// `cargo metadata` of the workspace in `dir`, resolved from its lock file for `host`.
fn metadata(dir: &Path, host: &str) -> Value {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(dir)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--locked",
            "--filter-platform",
            host,
        ])
        .output()
        .expect("run cargo metadata");
    assert!(
        out.status.success(),
        "cargo metadata in {}: {}",
        dir.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// What a workspace builds: its members, every package they depend on (dev-dependencies of the
/// members included), and those packages' normal and build dependencies.
fn built_packages(meta: &Value) -> BTreeSet<String> {
    let members: BTreeSet<String> = meta["workspace_members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|id| id.as_str().unwrap().to_owned())
        .collect();
    let deps: HashMap<&str, &Vec<Value>> = meta["resolve"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["id"].as_str().unwrap(), n["deps"].as_array().unwrap()))
        .collect();
    let mut built = BTreeSet::new();
    let mut todo: Vec<String> = members.iter().cloned().collect();
    while let Some(id) = todo.pop() {
        if !built.insert(id.clone()) {
            continue;
        }
        for dep in deps[id.as_str()] {
            let dev_only = dep["dep_kinds"]
                .as_array()
                .unwrap()
                .iter()
                .all(|k| k["kind"] == "dev");
            if members.contains(&id) || !dev_only {
                todo.push(dep["pkg"].as_str().unwrap().to_owned());
            }
        }
    }
    built
}

/// Checks one workspace; returns its highest dependency minimum and the package declaring it.
fn check(dir: &Path, host: &str) -> (RustVersion, String) {
    let meta = metadata(dir, host);
    let built = built_packages(&meta);
    let members: BTreeSet<&str> = meta["workspace_members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|id| id.as_str().unwrap())
        .collect();
    let packages = meta["packages"].as_array().unwrap();
    let highest = packages
        .iter()
        .filter(|p| built.contains(p["id"].as_str().unwrap()))
        .filter(|p| !members.contains(p["id"].as_str().unwrap()))
        .filter_map(|p| {
            let version = RustVersion::parse(p["rust_version"].as_str()?);
            Some((
                version,
                format!("{} {}", p["name"].as_str()?, p["version"].as_str()?),
            ))
        })
        .max()
        .expect("some dependency states a rust_version");
    for member in packages
        .iter()
        .filter(|p| members.contains(p["id"].as_str().unwrap()))
    {
        let name = member["name"].as_str().unwrap();
        let declared = member["rust_version"]
            .as_str()
            .unwrap_or_else(|| panic!("{name} in {} declares no rust-version", dir.display()));
        assert!(
            RustVersion::parse(declared) >= highest.0,
            "{name} in {} says rust-version {declared}, but {} needs Rust {}",
            dir.display(),
            highest.1,
            highest.0
        );
    }
    highest
}

#[test]
fn rust_version_is_at_least_what_every_locked_dependency_needs() {
    let host = host();
    let (main, needed_by) = check(&root(), &host);
    let (fuzz, _) = check(&root().join("fuzz"), &host);
    println!("main workspace: Rust {main} ({needed_by}); fuzz/: Rust {fuzz}");
    // The README states the same minimum as Cargo.toml.
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let declared = manifest
        .lines()
        .find_map(|l| l.strip_prefix("rust-version = \""))
        .and_then(|l| l.strip_suffix('"'))
        .expect("the workspace declares rust-version");
    assert!(
        readme.contains(&format!("Rust toolchain ({declared} or newer)")),
        "README.md states another minimum than rust-version = \"{declared}\""
    );
}

#[test]
fn rust_versions_compare_as_numbers() {
    let v = RustVersion::parse;
    assert!(v("1.100") > v("1.88"));
    assert_eq!(v("1.88"), v("1.88.0"));
    assert!(v("1.88.1") > v("1.88"));
    assert!(v("2.0") > v("1.99.9"));
}
