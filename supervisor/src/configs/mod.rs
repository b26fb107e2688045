//! The shipped configs, built into `harvemu`, and the one place where configs, node scripts and
//! scenarios are read from.
//!
//! Every file under the repository's `configs/` is compiled into the binary (`build.rs` lists
//! them; [`FILES`]), so an installed `harvemu` runs its default harvester, the shipped scenarios
//! and the soak from any directory, and `harvemu config export DIR` writes them out for editing.
//!
//! Contract: [`Source::read`] gives a file's text and says where it came from. For a path given
//! on the command line, or a default one (`configs/harvester.ron`, `configs/soak/soak_24h.ron`,
//! `configs/scenarios/NAME.ron` for a scenario's name), the first of these wins:
//! 1. the file at that path, relative to the working directory, when the disk has anything
//!    there: it is read with [`nodes::file::read_text`] (at most [`nodes::file::MAX_FILE`] bytes
//!    of UTF-8). A file that exists but cannot be read is an error, never a quiet switch to the
//!    built-in copy;
//! 2. the built-in copy, when the path is relative and names a shipped file once `.` and `..`
//!    are taken out of it (`./configs/scenarios/../harvester.ron` is `configs/harvester.ron`).
//!
//! So a path on the command line beats the default path, a file in the working directory beats
//! the built-in one, and the built-in copy is the last resort. A file named inside another (a
//! harvester's node scripts, a scenario's harvester config) is relative to the folder of the
//! file that names it; inside a built-in file it is looked up among the built-in files only, so
//! the built-in harvester always runs the built-in scripts, whatever lies in the working
//! directory. A built-in file is named `PATH (built in)` in every message and startup line.
//!
//! A folder given to `harvemu scenario` or `validate` stands for the `.ron` files directly in it,
//! on disk first, else built in, as [`expand`] says.

pub mod cli;

use nodes::Error;
use std::fmt;
use std::io;
use std::path::{Component, Path, PathBuf};

mod shipped {
    include!(concat!(env!("OUT_DIR"), "/shipped_configs.rs"));
}

/// Every shipped config file, sorted by path: its path from the repository's root
/// (`configs/harvester.ron`) and its bytes.
pub use shipped::FILES;

/// What follows a built-in file's path when it is named.
pub const BUILT_IN: &str = " (built in)";

/// Where a config, node script or scenario is read from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Source {
    /// Its path: on disk, or among [`FILES`] when built in.
    pub path: PathBuf,
    /// True for a built-in file.
    pub built_in: bool,
}

impl Source {
    /// A path as given on the command line or by default: the disk first, then the built-in
    /// copy.
    pub fn file(path: impl Into<PathBuf>) -> Source {
        Source {
            path: path.into(),
            built_in: false,
        }
    }

    /// The file that `rel` names inside this one: relative to this one's folder, and built in
    /// when this one is. A name written as every message writes a built-in file,
    /// `configs/harvester.ron (built in)`, is that built-in file wherever this one lies (a shrunk
    /// campaign run on disk names its built-in harvester so).
    pub fn beside(&self, rel: impl AsRef<Path>) -> Source {
        let rel = rel.as_ref();
        if let Some(name) = rel.to_str().and_then(|s| s.strip_suffix(BUILT_IN)) {
            return Source {
                path: PathBuf::from(name),
                built_in: true,
            };
        }
        let dir = self.path.parent().unwrap_or(Path::new(""));
        Source {
            path: dir.join(rel),
            built_in: self.built_in,
        }
    }

    /// The text, and the source it was really read from (the built-in copy when nothing is on
    /// disk at the path). Errors name the file, with `(built in)` for a built-in one.
    pub fn read(&self) -> Result<(Source, String), Error> {
        let mut not_found = None;
        if !self.built_in {
            match nodes::file::read_text(&self.path) {
                Err(Error::Io { source, .. }) if source.kind() == io::ErrorKind::NotFound => {
                    not_found = Some(source);
                }
                other => return other.map(|text| (self.clone(), text)),
            }
        }
        let Some((name, bytes)) = shipped(&self.path) else {
            return Err(self.missing(not_found));
        };
        let found = Source {
            path: PathBuf::from(name),
            built_in: true,
        };
        // Shipped files are UTF-8 (the tests read every one); this only guards the build.
        match std::str::from_utf8(bytes) {
            Ok(text) => Ok((found, text.to_string())),
            Err(e) => Err(Error::Io {
                path: found.to_string(),
                source: io::Error::new(io::ErrorKind::InvalidData, e),
            }),
        }
    }

    /// Reads the files this one names (an instance's template) as [`Source::read`] does, built
    /// in when this one is: the reader [`nodes::script::from_file_text`] takes.
    pub fn reader(&self) -> impl Fn(&Path) -> Result<(String, String), Error> + use<> {
        let built_in = self.built_in;
        move |path| {
            let (found, text) = Source {
                path: path.to_path_buf(),
                built_in,
            }
            .read()?;
            Ok((found.to_string(), text))
        }
    }

    /// Nothing at the path, on disk (`disk` says why) or built in.
    fn missing(&self, disk: Option<io::Error>) -> Error {
        let in_configs = key(&self.path).is_some_and(|k| k.starts_with("configs/"));
        let source = match disk {
            Some(e) if !in_configs => e,
            _ if self.built_in => io::Error::new(io::ErrorKind::NotFound, "no such built-in file"),
            _ => io::Error::new(
                io::ErrorKind::NotFound,
                "no such file in the working directory, and none built in \
                 (`harvemu config list` names the built-in ones)",
            ),
        };
        Error::Io {
            path: self.to_string(),
            source,
        }
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if self.built_in {
            f.write_str(BUILT_IN)?;
        }
        Ok(())
    }
}

/// The built-in file at `path`, if it names one: its name in [`FILES`] and its bytes.
pub fn shipped(path: &Path) -> Option<(&'static str, &'static [u8])> {
    let key = key(path)?;
    FILES
        .binary_search_by(|(name, _)| name.cmp(&key.as_str()))
        .ok()
        .map(|i| FILES[i])
}

/// A relative path with `.` and `..` taken out, its parts joined by `/`; `None` for an absolute
/// path, one that climbs above its start, or one that is not UTF-8.
fn key(path: &Path) -> Option<String> {
    let mut parts: Vec<&str> = Vec::new();
    for c in path.components() {
        match c {
            Component::Normal(p) => parts.push(p.to_str()?),
            Component::CurDir => {}
            Component::ParentDir => {
                parts.pop()?;
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(parts.join("/"))
}

/// A scenario given by its name: `bus_off` is `configs/FOLDER/bus_off.ron` when nothing is on
/// disk at `bus_off` itself. Anything else (a path with a folder or an extension, or a name
/// that is there) is taken as it is.
pub fn by_name(arg: &Path, folder: &str) -> PathBuf {
    if bare(arg) && absent(arg) {
        let mut file = arg.as_os_str().to_owned();
        file.push(".ron");
        Path::new("configs").join(folder).join(file)
    } else {
        arg.to_path_buf()
    }
}

/// The files an argument on the command line stands for, in this order of precedence:
/// 1. a folder on disk: every `.ron` file directly in it (not in its sub-folders), sorted by
///    name, names starting with a dot left out;
/// 2. anything else on disk: itself;
/// 3. a built-in folder (the path as in the repository, `configs/scenarios/conformance`): its
///    built-in `.ron` files, likewise;
/// 4. a name (no folder, no extension) when there is no file `configs/FOLDER/NAME.ron`, on disk
///    or built in, but a folder `configs/FOLDER/NAME`: that folder, on disk else built in, as
///    above (`conformance` for the shipped conformance suite);
/// 5. a path whose last part is a pattern (`*`, `?`, `[...]`) the shell left as it was: the
///    files it matches on disk, else the built-in `.ron` files of its folder it matches, sorted
///    by name; an error naming it when it matches none;
/// 6. itself, for [`by_name`] and [`Source::read`] to find or to report missing.
///
/// A folder without a `.ron` file is an error naming it. The paths of built-in files are their
/// names in [`FILES`]: [`Source::read`] finds them (nothing is on disk there).
pub fn expand(arg: &Path, folder: &str) -> crate::Result<Vec<PathBuf>> {
    if is_dir(arg) {
        return folder_on_disk(arg);
    }
    if !absent(arg) {
        return Ok(vec![arg.to_path_buf()]);
    }
    if let Some(files) = built_in_folder(arg)? {
        return Ok(files);
    }
    if bare(arg) {
        let file = by_name(arg, folder);
        let dir = Path::new("configs").join(folder).join(arg);
        if absent(&file) && shipped(&file).is_none() {
            if is_dir(&dir) {
                return folder_on_disk(&dir);
            }
            if absent(&dir)
                && let Some(files) = built_in_folder(&dir)?
            {
                return Ok(files);
            }
        }
    }
    if let Some(files) = pattern(arg)? {
        return Ok(files);
    }
    Ok(vec![arg.to_path_buf()])
}

/// The characters that make a path's last part a pattern.
const WILDCARDS: [char; 3] = ['*', '?', '['];

/// A path whose last part is a pattern that the shell left as it was (quoted, or matching
/// nothing there): the files it matches, sorted by name, hidden ones left out. On disk, else
/// (nothing matching there) among the built-in `.ron` files of that folder; an error when it
/// matches nothing. `None` for a path that is no pattern.
fn pattern(arg: &Path) -> crate::Result<Option<Vec<PathBuf>>> {
    let text = arg.to_string_lossy();
    let Some(name) = arg.file_name().map(|n| n.to_string_lossy()) else {
        return Ok(None);
    };
    if !name.contains(WILDCARDS) {
        return Ok(None);
    }
    let bad = |why: String| crate::Error::BadInput(format!("{text}: {why}"));
    let dir = arg.parent().filter(|p| !p.as_os_str().is_empty());
    if dir.is_some_and(|d| d.to_string_lossy().contains(WILDCARDS)) {
        return Err(bad(
            "a pattern in a folder's name is not expanded; only the last part of a \
                        path may be one"
                .into(),
        ));
    }
    let glob = glob::Pattern::new(&name).map_err(|e| bad(format!("not a valid pattern: {e}")))?;
    let options = glob::MatchOptions {
        require_literal_leading_dot: true,
        ..glob::MatchOptions::new()
    };
    let matches = |n: &str| glob.matches_with(n, options);
    let on_disk = dir.unwrap_or(Path::new("."));
    let mut found: Vec<PathBuf> = if is_dir(on_disk) {
        let cannot = |source| crate::Error::Input {
            path: on_disk.to_path_buf(),
            source,
        };
        let mut names = Vec::new();
        for entry in std::fs::read_dir(on_disk).map_err(cannot)? {
            let n = entry.map_err(cannot)?.file_name();
            if matches(&n.to_string_lossy()) {
                names.push(n);
            }
        }
        names.sort();
        // As the shell writes them: `./` only where the pattern had it.
        names
            .into_iter()
            .map(|n| dir.map_or(PathBuf::from(&n), |d| d.join(&n)))
            .collect()
    } else {
        Vec::new()
    };
    if found.is_empty() {
        let built_in = dir.and_then(shipped_folder).unwrap_or_default();
        found = built_in
            .into_iter()
            .filter(|full| {
                Path::new(full)
                    .file_name()
                    .is_some_and(|n| matches(&n.to_string_lossy()))
            })
            .map(PathBuf::from)
            .collect();
    }
    if found.is_empty() {
        return Err(bad(format!(
            "no file matches this pattern, on disk or built in (harvemu expands a pattern the \
             shell left as it was){}",
            dir.map_or(String::new(), |d| format!(
                "; {} stands for every .ron file directly in it",
                d.display()
            ))
        )));
    }
    Ok(Some(found))
}

/// The built-in `.ron` files directly in the folder `path` (not in its sub-folders), sorted by
/// name; `None` when no built-in file lies under that folder.
pub fn shipped_folder(path: &Path) -> Option<Vec<&'static str>> {
    let key = key(path)?;
    if key.is_empty() {
        return None;
    }
    let prefix = format!("{key}/");
    let under: Vec<(&'static str, &'static str)> = FILES
        .iter()
        .filter_map(|(name, _)| name.strip_prefix(prefix.as_str()).map(|rest| (*name, rest)))
        .collect();
    if under.is_empty() {
        return None;
    }
    Some(
        under
            .into_iter()
            .filter(|(_, rest)| !rest.contains('/') && !rest.starts_with('.') && rest.ends_with(".ron"))
            .map(|(name, _)| name)
            .collect(),
    )
}

/// A name alone: one part, no extension.
fn bare(arg: &Path) -> bool {
    arg.components().count() == 1
        && arg.extension().is_none()
        && matches!(arg.components().next(), Some(Component::Normal(_)))
}

/// Nothing on disk at `path` (not even a broken link).
fn absent(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_err_and(|e| e.kind() == io::ErrorKind::NotFound)
}

/// A folder on disk (through links).
fn is_dir(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_dir())
}

/// Every `.ron` file directly in the folder `dir` on disk, sorted by name, hidden ones left out;
/// an error when there is none.
fn folder_on_disk(dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let cannot = |source| crate::Error::Input {
        path: dir.to_path_buf(),
        source,
    };
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(cannot)? {
        let name = entry.map_err(cannot)?.file_name();
        let path = dir.join(&name);
        let hidden = name.as_encoded_bytes().starts_with(b".");
        if !hidden && path.extension().is_some_and(|e| e == "ron") && !is_dir(&path) {
            names.push(name);
        }
    }
    if names.is_empty() {
        return Err(no_ron(&dir.display().to_string()));
    }
    names.sort();
    Ok(names.into_iter().map(|n| dir.join(n)).collect())
}

/// The built-in `.ron` files directly in the folder `dir`, as paths; `None` when there is no
/// such built-in folder, an error when it holds no `.ron` file.
fn built_in_folder(dir: &Path) -> crate::Result<Option<Vec<PathBuf>>> {
    match shipped_folder(dir) {
        None => Ok(None),
        Some(names) if names.is_empty() => Err(no_ron(&format!("{}{BUILT_IN}", dir.display()))),
        Some(names) => Ok(Some(names.into_iter().map(PathBuf::from).collect())),
    }
}

fn no_ron(dir: &str) -> crate::Error {
    crate::Error::BadInput(format!(
        "{dir}: a folder with no .ron file directly in it (a folder stands for those; its \
         sub-folders are not searched)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_taken_apart_lexically() {
        assert_eq!(
            key(Path::new("./configs/scenarios/../harvester.ron")).as_deref(),
            Some("configs/harvester.ron")
        );
        assert_eq!(key(Path::new("../configs/harvester.ron")), None);
        assert_eq!(key(Path::new("/configs/harvester.ron")), None);
        assert!(shipped(Path::new("configs/nodes/../harvester.ron")).is_some());
        assert!(shipped(Path::new("harvester.ron")).is_none());
    }

    #[test]
    fn the_table_is_sorted_for_the_binary_search() {
        assert!(FILES.windows(2).all(|w| w[0].0 < w[1].0));
    }

    #[test]
    fn a_built_in_file_names_its_neighbours_in_the_built_in_tree() {
        let (h, _) = Source::file("configs/harvester.ron")
            .read()
            .unwrap_or_else(|e| panic!("{e}"));
        // The test runs in supervisor/, where configs/ is not: the built-in copy is read.
        assert!(h.built_in);
        assert_eq!(h.to_string(), "configs/harvester.ron (built in)");
        let missing = h.beside("nodes/zz.ron").read().unwrap_err().to_string();
        assert_eq!(missing, "configs/nodes/zz.ron (built in): no such built-in file");
    }

    #[test]
    fn a_name_written_as_built_in_is_the_built_in_file_from_anywhere() {
        let on_disk = Source::file("/somewhere/out/failing/run-3.ron");
        let h = on_disk.beside("configs/harvester.ron (built in)");
        assert_eq!(
            h,
            Source {
                path: "configs/harvester.ron".into(),
                built_in: true
            }
        );
        let (found, text) = h.read().unwrap_or_else(|e| panic!("{e}"));
        assert!(found.built_in && text.contains("Harvester("));
        // Without the suffix it is a path beside the file, as ever.
        let near = on_disk.beside("configs/harvester.ron");
        assert_eq!(
            near.path,
            Path::new("/somewhere/out/failing/configs/harvester.ron")
        );
        assert!(!near.built_in);
    }

    #[test]
    fn names_become_shipped_paths_only_when_nothing_is_there() {
        assert_eq!(
            by_name(Path::new("bus_off"), "scenarios"),
            Path::new("configs/scenarios/bus_off.ron")
        );
        assert_eq!(
            by_name(Path::new("bus_off.ron"), "scenarios"),
            Path::new("bus_off.ron")
        );
        assert_eq!(
            by_name(Path::new("x/bus_off"), "scenarios"),
            Path::new("x/bus_off")
        );
        // The crate's folder holds src: a name that is on disk is taken as it is.
        assert_eq!(by_name(Path::new("src"), "scenarios"), Path::new("src"));
    }

    #[test]
    fn a_built_in_folder_is_its_ron_files_directly_in_it() {
        let scenarios = shipped_folder(Path::new("configs/scenarios")).unwrap_or_default();
        assert!(
            scenarios.contains(&"configs/scenarios/bus_off.ron"),
            "{scenarios:?}"
        );
        assert!(scenarios.iter().all(|n| {
            n.strip_prefix("configs/scenarios/")
                .is_some_and(|rest| rest.ends_with(".ron") && !rest.contains('/'))
        }));
        assert!(scenarios.windows(2).all(|w| w[0] < w[1]));
        // What lies in sub-folders is built in too, and left out.
        assert!(
            FILES
                .iter()
                .any(|(n, _)| n.starts_with("configs/scenarios/conformance/"))
        );
        let nodes = shipped_folder(Path::new("./configs/scenarios/../nodes")).unwrap_or_default();
        assert!(nodes.contains(&"configs/nodes/b1.ron"), "{nodes:?}");
        assert!(
            FILES
                .iter()
                .any(|(n, _)| n.starts_with("configs/nodes/templates/"))
        );
        assert!(!nodes.iter().any(|n| n.contains("templates")), "{nodes:?}");
        // A file, a folder that is not built in, the root: no built-in folder.
        assert_eq!(shipped_folder(Path::new("configs/scenarios/bus_off.ron")), None);
        assert_eq!(shipped_folder(Path::new("configs/nowhere")), None);
        assert_eq!(shipped_folder(Path::new("configs/scen")), None);
        assert_eq!(shipped_folder(Path::new(".")), None);
        assert_eq!(shipped_folder(Path::new("/configs/scenarios")), None);
    }

    /// The tests run in supervisor/, where configs/ is not: built-in folders are found.
    #[test]
    fn a_name_or_path_of_a_built_in_folder_stands_for_its_files() {
        let expected: Vec<PathBuf> = shipped_folder(Path::new("configs/scenarios/conformance"))
            .unwrap_or_default()
            .into_iter()
            .map(PathBuf::from)
            .collect();
        assert!(!expected.is_empty());
        assert!(
            expected
                .iter()
                .all(|p| p.parent() == Some(Path::new("configs/scenarios/conformance")))
        );
        for arg in [
            "conformance",
            "configs/scenarios/conformance",
            "configs/scenarios/conformance/",
        ] {
            let files = expand(Path::new(arg), "scenarios").unwrap_or_else(|e| panic!("{arg}: {e}"));
            assert_eq!(files, expected, "{arg}");
        }
        // Each is read as the built-in copy.
        let (found, text) = Source::file(&expected[0])
            .read()
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(found.built_in && text.contains("Scenario("));
        // A name of a scenario file stays a name (by_name finds the file); a name of nothing,
        // or of a folder elsewhere than under the folder given, stays as it is.
        for arg in ["bus_off", "nothing", "nodes"] {
            assert_eq!(
                expand(Path::new(arg), "scenarios").unwrap_or_else(|e| panic!("{arg}: {e}")),
                [Path::new(arg)]
            );
        }
    }

    #[test]
    fn a_folder_on_disk_is_its_ron_files_sorted_hidden_and_sub_folders_left_out() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let d = dir.path();
        for f in [
            "b.ron",
            "a.ron",
            "c.RON.txt",
            ".hidden.ron",
            "notes.txt",
            "sub/x.ron",
            "folder.ron/y.ron",
        ] {
            let path = d.join(f);
            std::fs::create_dir_all(path.parent().unwrap_or(d)).unwrap_or_else(|e| panic!("{e}"));
            std::fs::write(path, "").unwrap_or_else(|e| panic!("{e}"));
        }
        let files = expand(d, "scenarios").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(files, [d.join("a.ron"), d.join("b.ron")]);
        // A file is itself.
        assert_eq!(
            expand(&d.join("notes.txt"), "scenarios").unwrap_or_else(|e| panic!("{e}")),
            [d.join("notes.txt")]
        );
        // No .ron file directly in it: an error naming it, exit code 2.
        let empty = d.join("empty");
        std::fs::create_dir_all(&empty).unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(empty.join(".x.ron"), "").unwrap_or_else(|e| panic!("{e}"));
        let e = expand(&empty, "scenarios").unwrap_err();
        assert_eq!(e.exit_code(), crate::exit::BAD_INPUT);
        assert_eq!(
            e.to_string(),
            format!(
                "{}: a folder with no .ron file directly in it (a folder stands for those; its sub-folders are not searched)",
                empty.display()
            )
        );
    }

    #[test]
    fn a_pattern_the_shell_left_is_expanded_on_disk_or_named_when_it_matches_nothing() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        for name in ["b.ron", "a.ron", ".hidden.ron", "c.txt"] {
            std::fs::write(dir.path().join(name), "").unwrap_or_else(|e| panic!("{e}"));
        }
        let found = expand(&dir.path().join("*.ron"), "scenarios").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(found, [dir.path().join("a.ron"), dir.path().join("b.ron")]);
        let none = dir.path().join("z*.ron");
        let e = expand(&none, "scenarios").unwrap_err();
        assert_eq!(e.exit_code(), crate::exit::BAD_INPUT);
        assert_eq!(
            e.to_string(),
            format!(
                "{}: no file matches this pattern, on disk or built in (harvemu expands a pattern \
                 the shell left as it was); {} stands for every .ron file directly in it",
                none.display(),
                dir.path().display()
            )
        );
        let deep = dir.path().join("*").join("x*.ron");
        let text = expand(&deep, "scenarios").unwrap_err().to_string();
        assert!(text.contains("only the last part of a path may be one"), "{text}");
        // A name with a `?` that is on disk is taken as it is.
        let odd = dir.path().join("what?.ron");
        std::fs::write(&odd, "").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(expand(&odd, "scenarios").unwrap_or_else(|e| panic!("{e}")), [odd]);
    }
}
