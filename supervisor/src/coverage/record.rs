//! One image's coverage as it is kept and merged: the counts with everything needed to write
//! its reports again (the code, the debug records, the sources), so that a merge needs no
//! other file.

use nodes::firmware::FirmwareSpec;
use nodes::firmware::coverage::{Count, Counts};
use serde::{Deserialize, Serialize};

/// What `NAME.coverage.json` says first.
pub const FORMAT: &str = "harvemu coverage 1";

/// One image's coverage.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ImageCoverage {
    /// [`FORMAT`].
    pub format: String,
    /// The image's file name (`c0_alarm.hex`): what merges go by.
    pub image: String,
    /// Where it was read, as messages name it (`configs/firmware/c0_alarm.hex (built in)`).
    pub source: String,
    /// SHA-256 of the image as its file holds it, hex.
    pub sha256: String,
    /// The nodes that ran it.
    pub nodes: Vec<String>,
    /// Runs merged into these counts.
    pub runs: u64,
    /// The code memory (hex) up to the end of what the image writes, as the first node ran it:
    /// listings are decoded from it.
    pub code: String,
    /// The address ranges the image writes, `[start, end)`.
    pub written: Vec<(u32, u32)>,
    /// Per address that ran: `[address, runs, jumped, fell through]`.
    pub counts: Vec<[u64; 4]>,
    /// Debug records found beside the image.
    pub debug: Option<Debug>,
}

/// Debug records of an image ([`nodes::firmware::Debug`]).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Debug {
    /// The file they came from.
    pub file: String,
    /// `(source file, line, first address)` of each source line.
    pub lines: Vec<(String, u32, u16)>,
    /// Each function's code.
    pub functions: Vec<Function>,
    /// The sources the lines name.
    pub sources: Vec<Source>,
}

/// A function's code.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Function {
    /// Its name.
    pub name: String,
    /// The module of a static function.
    pub module: Option<String>,
    /// Its first instruction.
    pub start: u16,
    /// Its last instruction, when known.
    pub end: Option<u16>,
}

/// A source file.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// Its name in the records.
    pub name: String,
    /// Where it was looked for.
    pub path: String,
    /// Its text, when found.
    pub text: Option<String>,
}

impl ImageCoverage {
    /// The coverage of `spec`'s image that `counts` hold, run by `nodes`, one run.
    pub fn of(spec: &FirmwareSpec, nodes: Vec<String>, counts: &Counts) -> ImageCoverage {
        let debug = spec.debug.as_ref().map(|d| Debug {
            file: d.file.clone(),
            lines: d
                .info
                .lines
                .iter()
                .map(|l| (l.file.clone(), l.line, l.address))
                .collect(),
            functions: d
                .info
                .functions
                .iter()
                .map(|f| Function {
                    name: f.name.clone(),
                    module: f.module.clone(),
                    start: f.start,
                    end: f.end,
                })
                .collect(),
            sources: d
                .sources
                .iter()
                .map(|s| Source {
                    name: s.name.clone(),
                    path: s.path.clone(),
                    text: s.text.clone(),
                })
                .collect(),
        });
        ImageCoverage {
            format: FORMAT.into(),
            image: file_name(&spec.image_file),
            source: spec.image_file.clone(),
            sha256: spec.image_sha256.clone(),
            nodes,
            runs: 1,
            code: hex(&spec.image.code[..code_end(spec)]),
            written: spec.image.written.iter().map(|r| (r.start, r.end)).collect(),
            counts: counts
                .iter()
                .map(|(a, c)| [u64::from(a), c.runs, c.taken, c.not_taken])
                .collect(),
            debug,
        }
    }

    /// The counts, by address.
    pub fn counts(&self) -> Counts {
        let mut counts = Counts::default();
        for &[a, runs, taken, not_taken] in &self.counts {
            if let Ok(a) = u16::try_from(a) {
                counts.add(
                    a,
                    Count {
                        runs,
                        taken,
                        not_taken,
                    },
                );
            }
        }
        counts
    }

    /// The code memory, decoded from [`ImageCoverage::code`] (bytes that do not decode read
    /// FFh, as unwritten code does).
    pub fn code_bytes(&self) -> Vec<u8> {
        let nibble = |c: u8| char::from(c).to_digit(16).and_then(|d| u8::try_from(d).ok());
        self.code
            .as_bytes()
            .chunks(2)
            .map(|p| match p {
                [h, l] => nibble(*h).zip(nibble(*l)).map_or(0xFF, |(h, l)| h << 4 | l),
                _ => 0xFF,
            })
            .collect()
    }

    /// A short name for its files: the image's file name without its extension.
    pub fn stem(&self) -> String {
        let name = std::path::Path::new(&self.image)
            .file_stem()
            .map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
        // Only characters every file system and viewer takes.
        name.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || "._-".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    }

    /// Adds `other`'s counts and runs: it must be of the same image.
    pub fn add(&mut self, other: &ImageCoverage) -> Result<(), String> {
        if other.sha256 != self.sha256 {
            return Err(format!(
                "{} is not the same image in both: {} (SHA-256 {}) and {} (SHA-256 {})",
                self.image,
                self.source,
                short(&self.sha256),
                other.source,
                short(&other.sha256)
            ));
        }
        let mut counts = self.counts();
        counts.merge(&other.counts());
        self.counts = counts
            .iter()
            .map(|(a, c)| [u64::from(a), c.runs, c.taken, c.not_taken])
            .collect();
        self.runs = self.runs.saturating_add(other.runs);
        for n in &other.nodes {
            if !self.nodes.contains(n) {
                self.nodes.push(n.clone());
            }
        }
        self.nodes.sort();
        if self.debug.is_none() {
            self.debug = other.debug.clone();
        }
        Ok(())
    }
}

/// The code memory up to the end of the last stretch the image writes: what listings decode.
fn code_end(spec: &FirmwareSpec) -> usize {
    let end = spec.image.written.iter().map(|r| r.end).max().unwrap_or(0);
    (end as usize).min(spec.image.code.len())
}

/// `bytes` in upper-case hex.
fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789ABCDEF";
    let mut out = String::with_capacity(2 * bytes.len());
    for b in bytes {
        out.push(char::from(DIGITS[usize::from(b >> 4)]));
        out.push(char::from(DIGITS[usize::from(b & 0xF)]));
    }
    out
}

/// The file name of `found` (a path as messages name it, perhaps with ` (built in)`).
fn file_name(found: &str) -> String {
    let path = found.strip_suffix(crate::configs::BUILT_IN).unwrap_or(found);
    std::path::Path::new(path)
        .file_name()
        .map_or_else(|| path.to_string(), |n| n.to_string_lossy().into_owned())
}

fn short(sha: &str) -> &str {
    sha.get(..12).unwrap_or(sha)
}

/// The coverage of a run, or of runs merged: one entry per image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coverage {
    /// The images, in the order first met.
    pub images: Vec<ImageCoverage>,
}

impl Coverage {
    /// Adds `other` (another run, or runs) to this: images of the same file are added, each
    /// must be the same image in both; others join. An error names the image that differs.
    pub fn merge(&mut self, other: &Coverage) -> Result<(), String> {
        for image in &other.images {
            match self.images.iter_mut().find(|i| i.image == image.image) {
                Some(mine) => mine.add(image)?,
                None => self.images.push(image.clone()),
            }
        }
        Ok(())
    }
}
