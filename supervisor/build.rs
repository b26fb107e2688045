//! Builds the table of the shipped configs that `harvemu` carries inside it: every file under the
//! repository's `configs/`, as `src/configs/mod.rs` describes.
//!
//! A build script rather than a macro crate such as include_dir: on stable Rust a macro cannot
//! tell Cargo about files added later, so a new node template would be missing until something
//! else forced a rebuild; a build script says `rerun-if-changed` for the folder (Cargo then looks
//! at every file under it) and for each folder in it, and `include_bytes!` makes every file's
//! content a dependency of the crate. No dependency is added either.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR").map(PathBuf::from);
    let out = std::env::var_os("OUT_DIR").map(PathBuf::from);
    let (Some(manifest), Some(out)) = (manifest, out) else {
        fail("CARGO_MANIFEST_DIR and OUT_DIR are set by Cargo: run this through cargo");
    };
    // `supervisor/shipped` is a link to the repository's `configs/`, inside the crate: packaged
    // (the Python package's source distribution, built away from the repository), the crate
    // then carries the files themselves. (Not named `configs`: run from `supervisor/`, harvemu
    // would take it for a config folder on disk.)
    let root = manifest.join("shipped");
    println!("cargo:rerun-if-changed={}", root.display());
    let mut files = Vec::new();
    walk(&root, "configs", &mut files);
    files.sort();
    if !files.iter().any(|(name, _)| name == "configs/harvester.ron") {
        fail(&format!(
            "{} has no harvester.ron: the shipped configs are missing",
            root.display()
        ));
    }
    let mut table = String::from(
        "/// Every shipped config file: its path from the repository's root, and its bytes.\n\
         pub static FILES: &[(&str, &[u8])] = &[\n",
    );
    for (name, path) in &files {
        let Some(path) = path.to_str() else {
            fail(&format!("{}: not a UTF-8 path", path.display()));
        };
        let _ = writeln!(table, "    ({name:?}, include_bytes!({path:?})),");
    }
    table.push_str("];\n");
    if let Err(e) = std::fs::write(out.join("shipped_configs.rs"), table) {
        fail(&format!("cannot write the table of shipped configs: {e}"));
    }
}

/// Collects every regular file under `dir` (following links), named by `prefix`/its path; names
/// starting with a dot (editors' swap files, .DS_Store) are left out.
fn walk(dir: &Path, prefix: &str, files: &mut Vec<(String, PathBuf)>) {
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| fail(&format!("{}: {e}", dir.display())));
    for entry in entries {
        let entry = entry.unwrap_or_else(|e| fail(&format!("{}: {e}", dir.display())));
        let path = entry.path();
        let Some(name) = entry.file_name().to_str().map(str::to_string) else {
            fail(&format!("{}: not a UTF-8 name", path.display()));
        };
        if name.starts_with('.') {
            continue;
        }
        let meta = std::fs::metadata(&path).unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
        let inner = format!("{prefix}/{name}");
        if meta.is_dir() {
            println!("cargo:rerun-if-changed={}", path.display());
            walk(&path, &inner, files);
        } else if meta.is_file() {
            files.push((inner, path));
        }
    }
}

fn fail(message: &str) -> ! {
    eprintln!("error: shipped configs: {message}");
    std::process::exit(1);
}
