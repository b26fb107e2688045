//! How a shrunk scenario names its harvester config, so that it is found from where the file
//! lies: built in, absolute, or relative to the file's folder.

use crate::configs::{BUILT_IN, Source};
use std::path::{Component, Path, PathBuf};

/// The harvester config as the scenario `file` names it: a built-in one as `PATH (built in)`,
/// an absolute path as it is, a relative one relative to the file's folder.
pub(super) fn config_field(source: &Source, file: &Path) -> String {
    if source.built_in {
        return format!("{}{BUILT_IN}", source.path.display());
    }
    if source.path.is_absolute() {
        return normal(&source.path).display().to_string();
    }
    seen_from(file, &source.path)
}

/// `target` (a path relative to the working directory, or absolute) as the file `file` names
/// it: relative to the file's folder.
pub(super) fn seen_from(file: &Path, target: &Path) -> String {
    let dir = file.parent().unwrap_or(Path::new(""));
    match (std::path::absolute(target), std::path::absolute(dir)) {
        (Ok(to), Ok(from)) => relative(&normal(&from), &normal(&to)).display().to_string(),
        (Ok(to), Err(_)) => normal(&to).display().to_string(),
        _ => target.display().to_string(),
    }
}

/// A path with `.` and `..` taken out lexically.
fn normal(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `to` relative to the folder `from` (both absolute and normal).
fn relative(from: &Path, to: &Path) -> PathBuf {
    let (a, b): (Vec<_>, Vec<_>) = (from.components().collect(), to.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_harvester_is_named_from_where_the_shrunk_file_lies() {
        let built_in = Source {
            path: "configs/harvester.ron".into(),
            built_in: true,
        };
        assert_eq!(
            config_field(&built_in, Path::new("/x/out/failing/run-1.ron")),
            "configs/harvester.ron (built in)"
        );
        let absolute = Source::file("/etc/harvemu/./h.ron");
        assert_eq!(
            config_field(&absolute, Path::new("out/failing/run-1.ron")),
            "/etc/harvemu/h.ron"
        );
        // Relative to the working directory, both: up out of out/failing, then down.
        let relative = Source::file("configs/../configs/harvester.ron");
        assert_eq!(
            config_field(&relative, Path::new("out/failing/run-1.ron")),
            "../../configs/harvester.ron"
        );
        assert_eq!(
            relative_to(Path::new("/a/b/c"), Path::new("/a/d/e.ron")),
            Path::new("../../d/e.ron")
        );
    }

    fn relative_to(from: &Path, to: &Path) -> PathBuf {
        relative(&normal(from), &normal(to))
    }
}
