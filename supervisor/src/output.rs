//! Output files (traces, HTML reports, JUnit XML, DBCs): complete or absent.
//!
//! Contract: an output to a regular file (or to a name that does not exist yet) is written to a
//! temporary file in the same folder, flushed and synced, then renamed over the name: a reader
//! never sees half of one, and an output that could not be written completely (a full disk, a
//! file-size limit) leaves the name as it was. An output to anything else that exists (a pipe, a
//! FIFO, a character device, a socket) or to a name under `/dev/` or `/proc/` (`/dev/stdout`)
//! is written to directly, as a stream. Every failure, on creating, writing, flushing, syncing or
//! renaming, is an [`Error::Output`] naming the file, with the I/O error as its source.

use crate::{Error, Result};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use tempfile::NamedTempFile;

/// An output being written.
pub struct Output {
    path: PathBuf,
    file: BufWriter<File>,
    /// The temporary file of a regular output (`None` for a stream).
    temp: Option<NamedTempFile>,
}

/// "cannot VERB PATH: why", without the temporary file's name that some errors carry.
pub fn failed(verb: &'static str, path: &Path, e: io::Error) -> Error {
    // tempfile appends the temporary file's name (` at path "..."`), which means nothing to the
    // user: the file they named is said instead. Its error type is private, so the cause is
    // rebuilt from the text before the name, with the same kind.
    let text = e.to_string();
    let source = match text.split_once(" at path \"") {
        Some((why, _)) => io::Error::new(e.kind(), why),
        None => e,
    };
    Error::Output {
        verb,
        what: path.display().to_string(),
        source,
    }
}

/// Writes `text` to standard output. A reader that went away (a closed pipe: `harvemu protocol |
/// head`) ends the output quietly, as it ends any Unix filter; any other failure (`> /dev/full`)
/// is an [`Error::Output`] naming standard output. Unlike `println!`, never panics.
pub fn stdout(text: &str) -> Result<()> {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != io::ErrorKind::BrokenPipe => {
            Err(failed("write", Path::new("standard output"), e))
        }
        _ => Ok(()),
    }
}

/// True when `path` is written as a stream rather than replaced as a whole.
pub fn is_stream(path: &Path) -> bool {
    if path.starts_with("/dev/") || path.starts_with("/proc/") {
        return true;
    }
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

impl Output {
    /// Starts the output to `path`: its temporary file, or the stream opened.
    pub fn create(path: &Path) -> Result<Output> {
        if is_stream(path) {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| failed("create", path, e))?;
            return Ok(Output {
                path: path.to_path_buf(),
                file: BufWriter::new(file),
                temp: None,
            });
        }
        // A symbolic link keeps pointing at the file it names: that file is what is replaced.
        let target = match std::fs::symlink_metadata(path) {
            Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(path).unwrap_or(path.into()),
            _ => path.to_path_buf(),
        };
        if target.is_dir() {
            let source = io::Error::new(io::ErrorKind::IsADirectory, "it is a directory");
            return Err(failed("create", path, source));
        }
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = target
            .file_name()
            .map_or("output".into(), |n| n.to_string_lossy().into_owned());
        // 0666 less the umask, as File::create would give (a temporary file is 0600 otherwise).
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(".part")
            .permissions(std::fs::Permissions::from_mode(0o666))
            .tempfile_in(dir)
            .map_err(|e| failed("create", path, e))?;
        let file = temp
            .as_file()
            .try_clone()
            .map_err(|e| failed("create", path, e))?;
        Ok(Output {
            path: target,
            file: BufWriter::new(file),
            temp: Some(temp),
        })
    }

    /// The name it is written to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Ends the output: flushed, and for a regular file synced and put in place. Dropping an
    /// output instead leaves the name as it was.
    pub fn commit(mut self) -> Result<()> {
        let path = self.path.clone();
        self.file.flush().map_err(|e| failed("write", &path, e))?;
        if let Some(temp) = self.temp.take() {
            temp.as_file().sync_all().map_err(|e| failed("write", &path, e))?;
            temp.persist(&path)
                .map_err(|e| failed("create", &path, e.error))?;
        }
        Ok(())
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

/// A regular file's output can go back (BLF and MF4 fill in their headers at the end); a stream
/// cannot, and says so with the system's error.
impl io::Seek for Output {
    fn seek(&mut self, pos: io::SeekFrom) -> io::Result<u64> {
        self.file.seek(pos)
    }
}

/// Writes `bytes` to `path`, wholly or not at all (for a regular file).
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut out = Output::create(path)?;
    out.write_all(bytes).map_err(|e| failed("write", path, e))?;
    out.commit()
}

/// Where `path` leads: its canonical form when it exists, else its folder's with its name, else
/// the path made absolute. Two names for one file (`./t.log`, `t.log`, a symbolic link to it)
/// lead to the same place.
fn place(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    match (absolute.parent(), absolute.file_name()) {
        (Some(dir), Some(name)) => std::fs::canonicalize(dir).map_or(absolute.clone(), |d| d.join(name)),
        _ => absolute,
    }
}

/// Refuses, before anything runs, two outputs of one run on the same file, and an output on a
/// file the run reads: one would overwrite the other. `outputs` and `inputs` are the options'
/// names (`--record`, `TRACE`) with their paths. Streams (`/dev/null`, `/dev/stdout`, a pipe)
/// may be shared: writing two outputs to `/dev/null` loses nothing that was wanted. An input
/// that is not on disk (a built-in config's name) is no file to overwrite.
pub fn distinct(outputs: &[(&str, Option<&Path>)], inputs: &[(&str, &Path)]) -> Result<()> {
    let outputs: Vec<(&str, &Path, PathBuf)> = outputs
        .iter()
        .filter_map(|(name, path)| path.map(|p| (*name, p)))
        .filter(|(_, p)| !is_stream(p))
        .map(|(name, p)| (name, p, place(p)))
        .collect();
    for (k, (name, path, at)) in outputs.iter().enumerate() {
        if let Some((other, _, _)) = outputs[..k].iter().find(|o| &o.2 == at) {
            return Err(Error::BadInput(format!(
                "{other} and {name} both write {}: one would overwrite the other; give each \
                 its own file",
                path.display()
            )));
        }
        for (input, source) in inputs {
            if source.exists() && &place(source) == at {
                return Err(Error::BadInput(format!(
                    "{name} {} is the file {input} reads: writing it would destroy what is \
                     read; write elsewhere",
                    path.display()
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("harvemu-output-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_file_appears_only_when_committed_and_nothing_is_left_beside_it() {
        let d = dir("commit");
        let path = d.join("a.txt");
        std::fs::write(&path, "old").unwrap();
        let mut out = Output::create(&path).unwrap();
        out.write_all(b"new text").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        drop(out);
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "old",
            "dropped: left as it was"
        );
        assert_eq!(
            std::fs::read_dir(&d).unwrap().count(),
            1,
            "no temporary file left"
        );
        write_whole(&path, b"new text").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new text");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_ne!(
            mode & 0o044,
            0,
            "readable by others as File::create makes it: {mode:o}"
        );
    }

    #[test]
    fn device_and_missing_folder() {
        assert!(is_stream(Path::new("/dev/null")));
        assert!(is_stream(Path::new("/dev/stdout")));
        assert!(!is_stream(Path::new("Cargo.toml")));
        write_whole(Path::new("/dev/null"), b"x").unwrap();
        let e = write_whole(Path::new("/dev/full"), b"x").unwrap_err();
        assert_eq!(e.exit_code(), crate::exit::OUTPUT_FAILED);
        assert!(
            e.report().to_string().starts_with("cannot write /dev/full: "),
            "{e}"
        );
        let e = write_whole(Path::new("/nonexistent-folder/x.html"), b"x").unwrap_err();
        assert_eq!(
            e.report().to_string(),
            "cannot create /nonexistent-folder/x.html: No such file or directory (os error 2)"
        );
        let Error::Output { source, .. } = e else {
            panic!("not an output: {e:?}");
        };
        assert_eq!(source.kind(), io::ErrorKind::NotFound);
    }
}
