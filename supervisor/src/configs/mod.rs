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
    let bare = arg.components().count() == 1
        && arg.extension().is_none()
        && matches!(arg.components().next(), Some(Component::Normal(_)));
    let absent = std::fs::symlink_metadata(arg).is_err_and(|e| e.kind() == io::ErrorKind::NotFound);
    if bare && absent {
        let mut file = arg.as_os_str().to_owned();
        file.push(".ron");
        Path::new("configs").join(folder).join(file)
    } else {
        arg.to_path_buf()
    }
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
}
