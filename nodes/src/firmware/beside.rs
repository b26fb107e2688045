//! What a build leaves beside a firmware image, for coverage reports: SDCC's debug records
//! (`NAME.cdb` beside `NAME.hex`), else an assembler's listing (as31's `NAME.lst`, or sdas's
//! with the linker's addresses, `NAME.rst`, of `NAME.asm`), the linker's own output
//! (`NAME.ihx`), and the source files the records name.
//!
//! Contract: [`read`] finds them through the node file's reader, where the image was found.
//! None of them is needed: a file that is not there is left out. One that is there must belong
//! to the image: debug records outside the image or off its instructions
//! ([`DebugInfo::check`]), or an `.ihx` whose code differs from the image, are a problem naming
//! that file (the spec keeps them: only a run that counts coverage refuses them). A listing of
//! neither kind is not read.

use super::debuginfo::{self, DebugInfo};
use super::spec::Reader;
use crate::{Error, Problem};
use std::path::Path;

/// Debug information of an image, with the sources it names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Debug {
    /// The file it was read from, as named in messages.
    pub file: String,
    /// Where each source line's and function's code lies.
    pub info: DebugInfo,
    /// Each source file the lines name, in the order first named.
    pub sources: Vec<SourceFile>,
}

/// A source file that debug records name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceFile {
    /// Its name in the records (`c0_alarm.c`).
    pub name: String,
    /// Where it was looked for, as named in messages.
    pub path: String,
    /// Its text, when it was found.
    pub text: Option<String>,
}

/// A listing's reader: the listing's name and text, and its source's name.
type Parse = fn(&str, &str, &str) -> Result<DebugInfo, Error>;

/// `Ok(None)` for a file that is not there.
fn optional(read: Reader, path: &Path) -> Result<Option<(String, String)>, Error> {
    match read(path) {
        Ok(found) => Ok(Some(found)),
        Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// Reads what lies beside `image_path` (the image as its file holds it: `image`), the sources
/// in `sources` (a folder); problems go to `problems`.
pub fn read(
    image_path: &Path,
    image: &mcs51::Image,
    sources: &Path,
    read: Reader,
    problems: &mut Vec<Problem>,
) -> Option<Debug> {
    let mut refuse = |e: Error| match e {
        Error::Invalid(p) => problems.extend(p),
        e => problems.push(Problem::at(
            &image_path.display().to_string(),
            "image",
            e.to_string(),
        )),
    };
    match optional(read, &image_path.with_extension("ihx")) {
        Ok(Some((name, text))) => match mcs51::hex::parse(&text, image.code.len()) {
            Ok(built) if built.code == image.code && built.written == image.written => {}
            Ok(_) => refuse(Error::Invalid(vec![Problem {
                file: name,
                position: None,
                node: None,
                field: None,
                message: "differs from the image beside it: the debug files are of another build".into(),
            }])),
            Err(e) => refuse(Error::Invalid(vec![Problem {
                file: name,
                position: None,
                node: None,
                field: None,
                message: e.to_string(),
            }])),
        },
        Ok(None) => {}
        Err(e) => refuse(e),
    }
    let (file, info) = match optional(read, &image_path.with_extension("cdb")) {
        Ok(Some((name, text))) => match debuginfo::parse(&name, &text) {
            Ok(info) => (name, info),
            Err(e) => {
                refuse(e);
                return None;
            }
        },
        Ok(None) => {
            let asm = image_path.with_extension("asm");
            let asm_name = asm.file_name()?.to_str()?.to_string();
            let listings: [(&str, Parse); 2] = [
                ("lst", debuginfo::parse_as31_listing),
                ("rst", debuginfo::parse_sdas_listing),
            ];
            let mut found = None;
            for (extension, parse) in listings {
                match optional(read, &image_path.with_extension(extension)) {
                    Ok(Some((name, text))) => match parse(&name, &text, &asm_name) {
                        Ok(info) if !info.lines.is_empty() => {
                            found = Some((name, info));
                            break;
                        }
                        Ok(_) => {}
                        Err(e) => {
                            refuse(e);
                            return None;
                        }
                    },
                    Ok(None) => {}
                    Err(e) => {
                        refuse(e);
                        return None;
                    }
                }
            }
            found?
        }
        Err(e) => {
            refuse(e);
            return None;
        }
    };
    if let Err(e) = info.check(&file, image) {
        refuse(e);
        return None;
    }
    let mut sources_found: Vec<SourceFile> = Vec::new();
    for line in &info.lines {
        if sources_found.iter().any(|s| s.name == line.file) {
            continue;
        }
        // A name with a folder in it is not looked for outside the sources' folder.
        let Some(base) = Path::new(&line.file).file_name() else {
            continue;
        };
        let path = sources.join(base);
        let text = match optional(read, &path) {
            Ok(found) => found.map(|(_, text)| text),
            Err(e) => {
                refuse(e);
                None
            }
        };
        sources_found.push(SourceFile {
            name: line.file.clone(),
            path: path.display().to_string(),
            text,
        });
    }
    Some(Debug {
        file,
        info,
        sources: sources_found,
    })
}
