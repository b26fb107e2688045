//! Reading the text files harvemu takes: harvester configs, node scripts and their templates,
//! scenarios, firmware node files, Intel HEX images and their debug information. [`read_text`]
//! is the one function that reads them.
//!
//! Contract: [`read_text`] reads at most [`MAX_FILE`] + 1 bytes of a file, so a file over the
//! limit is refused as soon as that much has been read: `/dev/zero`, a FIFO that never ends or a
//! huge file costs no more than the limit in memory and ends at once. The refusal is
//! [`Error::Io`] naming the file and the limit. Text that is not UTF-8 is refused too.

use crate::Error;
use std::io::{self, Read};
use std::path::Path;

/// The largest input file read, bytes: 1 MiB, over seventy times the largest shipped one (the
/// C0 image's debug information, about 14 KiB) and over five times the Intel HEX text of a full
/// 64 KiB code memory (about 180 KiB).
pub const MAX_FILE: u64 = 1024 * 1024;

/// The text of the file at `path`, when it is at most [`MAX_FILE`] bytes of UTF-8.
pub fn read_text(path: &Path) -> Result<String, Error> {
    read_limited(path, MAX_FILE).map_err(|source| Error::Io {
        path: path.display().to_string(),
        source,
    })
}

fn read_limited(path: &Path, limit: u64) -> io::Result<String> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::FileTooLarge,
            format!(
                "larger than {} MiB ({limit} bytes), the limit for an input file",
                limit / (1024 * 1024)
            ),
        ));
    }
    String::from_utf8(bytes).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (byte {} is not)",
                e.utf8_error().valid_up_to() + 1
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("harvemu-nodes-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn a_file_of_the_limit_is_read_one_byte_more_is_refused() {
        let fits = scratch("fits.ron");
        std::fs::write(&fits, "x".repeat(MAX_FILE as usize)).unwrap();
        assert_eq!(read_text(&fits).unwrap().len() as u64, MAX_FILE);
        let over = scratch("over.ron");
        std::fs::write(&over, "x".repeat(MAX_FILE as usize + 1)).unwrap();
        let e = read_text(&over).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "{}: larger than 1 MiB (1048576 bytes), the limit for an input file",
                over.display()
            )
        );
        let _ = std::fs::remove_file(fits);
        let _ = std::fs::remove_file(over);
    }

    #[test]
    fn endless_input_ends_at_the_limit() {
        let e = read_text(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.starts_with("/dev/zero: larger than 1 MiB"), "{e}");
    }

    #[test]
    fn missing_and_non_utf8_files_are_errors_naming_the_file() {
        let missing = scratch("missing.ron");
        let e = read_text(&missing).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", missing.display())), "{e}");
        let latin1 = scratch("latin1.ron");
        std::fs::write(&latin1, b"(name: \"caf\xe9\")").unwrap();
        let e = read_text(&latin1).unwrap_err().to_string();
        assert!(e.ends_with("not UTF-8 text (byte 12 is not)"), "{e}");
    }
}
