//! lcov's tracefile format (`.info`, as `geninfo` writes it and `genhtml` reads it) from an
//! image's counts and its debug records.
//!
//! A line record's code runs from its address to the next address where another record's
//! code starts (or its function ends); a source line may have several such stretches (a `for`
//! has its start, its test and its step). A stretch is entered as often as its first
//! instruction ran, or, when that never ran but others did (code only jumped into), as often as
//! its most-run instruction: so a line whose code ran at all counts as run. A line's count
//! (`DA`) is its most-entered stretch's. Each conditional jump in it is a pair of branches
//! (`BRDA`: jumped, fell through), `-` while the jump never ran. A function (`FN`,
//! `FNDA`) is at the first line of its code and counts the runs of its first instruction.

use super::listing::Item;
use super::record::ImageCoverage;
use nodes::firmware::coverage::Counts;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// What one source file's record holds.
#[derive(Default)]
struct FileRecord {
    /// Line → its count.
    lines: BTreeMap<u32, u64>,
    /// (line, block, branch, taken or `None` for never run).
    branches: Vec<(u32, usize, u8, Option<u64>)>,
    /// (first line, name, count).
    functions: Vec<(u32, String, u64)>,
}

/// The tracefile of `image` with its counts and instructions ([`super::listing::items`]),
/// its sources named by `source_path` (a record's file name → the path `SF` gives); `None`
/// when it has no debug records.
pub fn tracefile(
    image: &ImageCoverage,
    counts: &Counts,
    items: &[Item],
    source_path: impl Fn(&str) -> String,
) -> Option<String> {
    let debug = image.debug.as_ref()?;
    let mut files: BTreeMap<String, FileRecord> = BTreeMap::new();
    // Each distinct start address, with the lines that start there.
    let mut starts: Vec<u16> = debug.lines.iter().map(|l| l.2).collect();
    starts.extend(
        debug
            .functions
            .iter()
            .filter_map(|f| f.end.map(|e| e.saturating_add(1))),
    );
    starts.sort_unstable();
    starts.dedup();
    let mut block = 0;
    for (n, (file, line, address)) in debug.lines.iter().enumerate() {
        let end = starts
            .iter()
            .find(|&&s| s > *address)
            .copied()
            .unwrap_or(u16::MAX);
        let within: Vec<&Item> = items
            .iter()
            .filter(|i| !i.data && i.address >= *address && i.address < end)
            .collect();
        // Entered as often as its first instruction ran; a stretch only jumped into counts its
        // most-run instruction.
        let first = counts.get(*address).runs;
        let count = if first > 0 {
            first
        } else {
            within
                .iter()
                .map(|i| counts.get(i.address).runs)
                .max()
                .unwrap_or(0)
        };
        let record = files.entry(file.clone()).or_default();
        let seen = record.lines.entry(*line).or_insert(0);
        *seen = (*seen).max(count);
        // Lines that share a start share its code: its branches go to the last of them.
        let last_here = debug.lines.get(n + 1).is_none_or(|next| next.2 != *address);
        if last_here {
            for i in within.iter().filter(|i| i.branches) {
                let c = counts.get(i.address);
                let ran = c.runs > 0;
                record.branches.push((*line, block, 0, ran.then_some(c.taken)));
                record
                    .branches
                    .push((*line, block, 1, ran.then_some(c.not_taken)));
                block += 1;
            }
        }
    }
    for f in &debug.functions {
        let first = debug
            .lines
            .iter()
            .filter(|l| l.2 >= f.start && f.end.is_none_or(|e| l.2 <= e))
            .min_by_key(|l| (l.2, l.1));
        if let Some((file, line, _)) = first {
            let name = match &f.module {
                Some(m) => format!("{m}.{}", f.name),
                None => f.name.clone(),
            };
            let runs = counts.get(f.start).runs;
            files
                .entry(file.clone())
                .or_default()
                .functions
                .push((*line, name, runs));
        }
    }
    Some(render(&files, &source_path))
}

fn render(files: &BTreeMap<String, FileRecord>, source_path: &impl Fn(&str) -> String) -> String {
    let mut out = String::new();
    for (file, r) in files {
        let _ = writeln!(out, "TN:\nSF:{}", source_path(file));
        for (line, name, _) in &r.functions {
            let _ = writeln!(out, "FN:{line},{name}");
        }
        for (_, name, runs) in &r.functions {
            let _ = writeln!(out, "FNDA:{runs},{name}");
        }
        let hit = r.functions.iter().filter(|f| f.2 > 0).count();
        let _ = writeln!(out, "FNF:{}\nFNH:{hit}", r.functions.len());
        for (line, block, branch, taken) in &r.branches {
            match taken {
                Some(t) => {
                    let _ = writeln!(out, "BRDA:{line},{block},{branch},{t}");
                }
                None => {
                    let _ = writeln!(out, "BRDA:{line},{block},{branch},-");
                }
            }
        }
        let taken = r.branches.iter().filter(|b| b.3.is_some_and(|t| t > 0)).count();
        let _ = writeln!(out, "BRF:{}\nBRH:{taken}", r.branches.len());
        for (line, count) in &r.lines {
            let _ = writeln!(out, "DA:{line},{count}");
        }
        let hit = r.lines.values().filter(|&&c| c > 0).count();
        let _ = writeln!(out, "LF:{}\nLH:{hit}\nend_of_record", r.lines.len());
    }
    out
}
