//! SDCC's debug records for an image (the `.cdb` file `sdcc --debug` writes beside it): which C
//! source line and which function each code address belongs to, for coverage reports.
//!
//! Contract: [`parse`] reads the linker's records of the `.cdb` format (SDCC's "CDB file
//! format" document): line records `L:C$file$line$level$block:address`, function symbols
//! `F:G$name$...` (global) and `F:F<module>$name$...` (static to `module`), and the start
//! (`L:G$name$...:address`, `L:F<module>$name$...:address`) and end (`L:XG$...`, `L:XF<module>$...`)
//! of each function's code. Every other record (types, variables, assembler lines) is skipped,
//! but every linker record (`L:`) must end in a code address (hex, 0 to FFFF) and every line
//! record must name its file and line: a record that does not is an error naming the file and
//! the line, and nothing is returned. Lines come sorted by address, then by source line;
//! functions by start.
//!
//! [`parse_as31_listing`] reads the same facts, lines only, from an as31 listing (`as31 -l`):
//! one listing line per source line, `ADDR: BYTES` before the source text, so listing line `n`
//! is source line `n`. A line that places bytes is an instruction's unless its statement is a
//! directive (`.db`, `.dw`, `.byte`, ...: data).
//!
//! [`parse_sdas_listing`] reads them from sdas's listing with the linker's addresses
//! (`NAME.rst`): a row with bytes and a cycle count in brackets is an instruction, and gives
//! its source line's number.
//!
//! [`DebugInfo::check`] holds the records to the image they claim to describe: every line and
//! function address inside what the image writes, and inside a function on an instruction
//! boundary, the instructions decoded from the function's start.

use crate::error::{Error, Problem};

/// A C source line's code starts at `address`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceLine {
    /// The first code address of the line.
    pub address: u16,
    /// The source file, as the compiler named it.
    pub file: String,
    /// Its line number, from 1.
    pub line: u32,
}

/// A function's code: from `start`, its last instruction at `end` (when the record is there).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Function {
    /// Its name in the source.
    pub name: String,
    /// The module (source file without `.c`) of a static function; `None` for a global one.
    pub module: Option<String>,
    /// The address of its first instruction.
    pub start: u16,
    /// The address of its last instruction, when the file gives it.
    pub end: Option<u16>,
}

/// What a `.cdb` file says of an image's code.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DebugInfo {
    /// Where each C source line's code starts.
    pub lines: Vec<SourceLine>,
    /// The functions whose code the file places.
    pub functions: Vec<Function>,
}

/// A symbol's scope and name: `G$name` is global, `F<module>$name` static to the module.
fn scoped(text: &str) -> Option<(Option<String>, String)> {
    let (scope, rest) = text.split_once('$')?;
    let name = rest.split('$').next()?.to_string();
    match scope.strip_prefix('F') {
        _ if scope == "G" => Some((None, name)),
        Some(module) if !module.is_empty() => Some((Some(module.to_string()), name)),
        _ => None,
    }
}

/// Reads `text`, the `.cdb` file `file` (named in errors).
pub fn parse(file: &str, text: &str) -> Result<DebugInfo, Error> {
    let problem = |n: usize, message: String| problem(file, n, message);
    let mut names = Vec::new();
    let mut starts = Vec::new();
    let mut ends = Vec::new();
    let mut lines = Vec::new();
    for (n, record) in text.lines().enumerate() {
        let record = record.trim_end();
        if let Some(symbol) = record.strip_prefix("F:") {
            if let Some(scoped) = scoped(symbol) {
                names.push(scoped);
            }
            continue;
        }
        let Some(link) = record.strip_prefix("L:") else {
            continue;
        };
        let Some((key, address)) = link.rsplit_once(':') else {
            return Err(problem(
                n,
                format!("a linker record without an address: `{record}`"),
            ));
        };
        let address = u16::from_str_radix(address, 16)
            .map_err(|_| problem(n, format!("`{address}` is not a code address (hex, 0 to FFFF)")))?;
        if let Some(rest) = key.strip_prefix("C$") {
            let mut fields = rest.split('$');
            let (Some(source), Some(line)) = (fields.next(), fields.next()) else {
                return Err(problem(
                    n,
                    format!("a line record without its file and line: `{record}`"),
                ));
            };
            let line = line
                .parse()
                .map_err(|_| problem(n, format!("`{line}` is not a line number")))?;
            lines.push(SourceLine {
                address,
                file: source.to_string(),
                line,
            });
        } else if let Some(end) = key.strip_prefix('X') {
            if let Some(symbol) = scoped(end) {
                ends.push((symbol, address));
            }
        } else if let Some(symbol) = scoped(key) {
            starts.push((symbol, address));
        }
    }
    // A start record is a function's only when a function symbol of that name and scope is
    // declared (variables have start records too).
    let mut functions: Vec<Function> = starts
        .into_iter()
        .filter(|(symbol, _)| names.contains(symbol))
        .map(|((module, name), start)| Function {
            end: ends
                .iter()
                .find(|(s, _)| s.0 == module && s.1 == name)
                .map(|&(_, a)| a),
            name,
            module,
            start,
        })
        .collect();
    functions.sort_by_key(|f| f.start);
    lines.sort_by_key(|l| (l.address, l.line));
    Ok(DebugInfo { lines, functions })
}

/// Reads an as31 listing `text` (file `file`, named in errors) of the source `source`; no
/// lines when it places no instruction as as31 lists them (another assembler's listing).
pub fn parse_as31_listing(file: &str, text: &str, source: &str) -> Result<DebugInfo, Error> {
    let mut lines = Vec::new();
    for (n, row) in text.lines().enumerate() {
        // `0030: 75 81 60     START:  MOV SP, #60H`; a line without code has no address.
        let Some((address, rest)) = row.split_once(": ") else {
            continue;
        };
        if address.len() != 4 || !address.bytes().all(|b| b.is_ascii_hexdigit()) {
            continue;
        }
        let address =
            u16::from_str_radix(address, 16).map_err(|_| problem(file, n, format!("`{address}`")))?;
        let mut words = rest.split_whitespace().peekable();
        let bytes = skip_bytes(&mut words);
        let mut statement = words.next().unwrap_or("");
        if statement.ends_with(':') {
            statement = words.next().unwrap_or("");
        }
        if bytes == 0 || statement.starts_with('.') || statement.starts_with(';') {
            continue;
        }
        let line = u32::try_from(n + 1).map_err(|_| problem(file, n, "too many lines".into()))?;
        lines.push(SourceLine {
            address,
            file: source.to_string(),
            line,
        });
    }
    lines.sort_by_key(|l| (l.address, l.line));
    Ok(DebugInfo {
        lines,
        functions: Vec::new(),
    })
}

/// Reads an sdas listing with the linker's addresses (`NAME.rst`, from `sdas8051 -l` and
/// `sdld -u`) `text` (file `file`) of the source `source`. A row
/// `000002 DF FE [24] 4 delay: djnz r7, delay` is an instruction (address, bytes, cycles in
/// brackets, then its source line's number); rows without cycles (data, directives) are not.
/// No lines when there is none.
pub fn parse_sdas_listing(file: &str, text: &str, source: &str) -> Result<DebugInfo, Error> {
    let mut lines = Vec::new();
    for (n, row) in text.lines().enumerate() {
        let mut words = row.split_whitespace().peekable();
        let Some(address) = words.next() else { continue };
        if address.len() != 6 || !address.bytes().all(|b| b.is_ascii_hexdigit()) {
            continue;
        }
        let bytes = skip_bytes(&mut words);
        let cycles = words
            .next()
            .is_some_and(|w| w.starts_with('[') && w.ends_with(']'));
        if bytes == 0 || !cycles {
            continue;
        }
        let line = words.next().and_then(|w| w.parse::<u32>().ok()).ok_or_else(|| {
            problem(
                file,
                n,
                "an instruction row without its source line's number".into(),
            )
        })?;
        let address = u32::from_str_radix(address, 16)
            .ok()
            .and_then(|a| u16::try_from(a).ok())
            .ok_or_else(|| problem(file, n, format!("`{address}` is not a code address (0 to FFFF)")))?;
        lines.push(SourceLine {
            address,
            file: source.to_string(),
            line,
        });
    }
    lines.sort_by_key(|l| (l.address, l.line));
    Ok(DebugInfo {
        lines,
        functions: Vec::new(),
    })
}

/// Takes the code bytes (two hex digits each) a listing row places after its address: how many.
fn skip_bytes<'a>(words: &mut std::iter::Peekable<impl Iterator<Item = &'a str>>) -> usize {
    let mut bytes = 0;
    while words
        .next_if(|w| w.len() == 2 && w.bytes().all(|b| b.is_ascii_hexdigit()))
        .is_some()
    {
        bytes += 1;
    }
    bytes
}

fn problem(file: &str, n: usize, message: String) -> Error {
    Error::Invalid(vec![Problem {
        file: file.to_string(),
        position: Some((n + 1, 1)),
        node: None,
        field: None,
        message,
    }])
}

impl DebugInfo {
    /// Whether these records describe `image` (see the module docs); `file` is named in the
    /// error, with the first record that does not fit.
    pub fn check(&self, file: &str, image: &mcs51::Image) -> Result<(), Error> {
        let written = |a: u16| image.written.iter().any(|r| r.contains(&u32::from(a)));
        let refuse = |message: String| {
            Err(Error::Invalid(vec![Problem {
                file: file.to_string(),
                position: None,
                node: None,
                field: None,
                message: format!("{message}: the debug information does not belong to this image"),
            }]))
        };
        for f in &self.functions {
            for a in std::iter::once(f.start).chain(f.end) {
                if !written(a) {
                    return refuse(format!("function {} at {a:04X}h lies outside the image", f.name));
                }
            }
        }
        for l in &self.lines {
            if !written(l.address) {
                return refuse(format!(
                    "{} line {} at {:04X}h lies outside the image",
                    l.file, l.line, l.address
                ));
            }
            let within = self
                .functions
                .iter()
                .find(|f| f.start <= l.address && f.end.is_some_and(|e| l.address <= e));
            if let Some(f) = within
                && !instruction_starts(image, f.start, l.address)
            {
                return refuse(format!(
                    "{} line {} at {:04X}h is not on an instruction of {}",
                    l.file, l.line, l.address, f.name
                ));
            }
        }
        Ok(())
    }
}

/// Whether decoding instructions one after another from `from` meets `at`.
fn instruction_starts(image: &mcs51::Image, from: u16, at: u16) -> bool {
    let mut pc = from;
    while pc < at {
        let (_, len) = mcs51::disasm(&image.code, pc);
        match pc.checked_add(len.max(1)) {
            Some(next) => pc = next,
            None => return false,
        }
    }
    pc == at
}

#[cfg(test)]
mod tests {
    use super::*;

    // Records as SDCC 4 writes them for a file `m.c` with a global `main`, a static `f` and a
    // global variable `ticks` (whose start record is not a function's).
    const CDB: &str = "M:m
F:G$main$0_0$0({2}DF,SV:S),C,0,0,0,0,0
F:Fm$f$0_0$0({2}DF,SI:U),C,0,0,0,0,0
S:G$ticks$0_0$0({1}SC:U),E,0,0
L:G$ticks$0_0$0:8
L:C$m.c$12$1_0$2:1D7
L:C$m.c$10$0_0$2:1D7
L:G$main$0$0:1D7
L:Fm$f$0$0:AC
L:C$m.c$4$1_0$1:AC
L:XFm$f$0$0:100
L:XG$main$0$0:1F0
L:A$m$120:1D7
";

    #[test]
    fn lines_and_functions_come_from_their_records() {
        let info = parse("m.cdb", CDB).unwrap();
        let line = |address, line| SourceLine {
            address,
            file: "m.c".into(),
            line,
        };
        assert_eq!(info.lines, vec![line(0xAC, 4), line(0x1D7, 10), line(0x1D7, 12)]);
        assert_eq!(
            info.functions,
            vec![
                Function {
                    name: "f".into(),
                    module: Some("m".into()),
                    start: 0xAC,
                    end: Some(0x100)
                },
                Function {
                    name: "main".into(),
                    module: None,
                    start: 0x1D7,
                    end: Some(0x1F0)
                },
            ]
        );
    }

    #[test]
    fn listings_give_the_lines_of_instructions_only() {
        // as31 -l: listing line n is source line n.
        let as31 = "; comment\n0000:                      .org    0000H\n0000: 02 00 30             LJMP    START\n0030: 75 81 60     START:  MOV     SP, #60H\n0033: 01 02                .db 1, 2\n";
        let info = parse_as31_listing("p.lst", as31, "p.asm").unwrap();
        let at: Vec<(u16, u32)> = info.lines.iter().map(|l| (l.address, l.line)).collect();
        assert_eq!(at, [(0x0000, 3), (0x0030, 4)]);
        // sdas + sdld -u: the line number is a column of its own.
        let sdas = "      000000                          2 \t.org\t0x0000\n      000000 7F C8            [12]    3 start:\tmov\tr7, #200\n      000006 01 02                    6 \t.db\t0x01, 0x02\n      000008 80 FE            [24]    7 loop:\tsjmp\tloop\n";
        let info = parse_sdas_listing("p.rst", sdas, "p.asm").unwrap();
        let at: Vec<(u16, u32)> = info.lines.iter().map(|l| (l.address, l.line)).collect();
        assert_eq!(at, [(0x0000, 3), (0x0008, 7)]);
        assert!(
            parse_as31_listing("p.lst", sdas, "p.asm")
                .unwrap()
                .lines
                .is_empty()
        );
    }

    #[test]
    fn a_malformed_record_is_refused_with_its_line() {
        for bad in ["L:C$m.c$4$1_0$1:XYZ", "L:C$m.c$four$1_0$1:AC", "L:G$main"] {
            let text = format!("M:m\n{bad}\n");
            let message = parse("m.cdb", &text).unwrap_err().to_string();
            assert!(message.contains("m.cdb:2:1: "), "{message}");
        }
        let message = parse("m.cdb", "L:C$m.c$4$1_0$1:10000\n").unwrap_err().to_string();
        assert!(message.contains("`10000` is not a code address"), "{message}");
    }
}
