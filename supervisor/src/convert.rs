//! `harvemu convert IN OUT`: a trace from one format into another, saying what the target
//! cannot carry.
//!
//! Contract: IN is read as its bytes say ([`crate::traces`]); OUT is written in the format its
//! name asks for (or `--format`'s), through the same writers as `--record`, and appears only
//! once complete ([`crate::output`]). Every record is carried over with its time, interface and
//! entry as far as the target keeps them ([`Keeps`]); what it drops is counted and said on
//! standard error, one line per kind of loss, after the summary. A target that dates its
//! measurement (ASC, BLF, MF4) is dated at IN's first record, to the millisecond below it. Bad
//! input (a bad record, a format its name denies) is exit 2 with nothing written; a stop signal
//! leaves OUT as it was and exits with 128 + the signal's number.

use crate::exit::Ended;
use crate::traces;
use bus::time::Stamp;
use bus::tracefile::{Entry, ErrorFrames, FileFormat};
use std::collections::BTreeSet;
use std::path::PathBuf;

/// Arguments of `harvemu convert`.
#[derive(clap::Args)]
pub struct Args {
    /// The trace to read: a candump log, Vector ASC or BLF, pcapng or pcap, or MF4 (told by its
    /// first bytes, which must agree with its name's extension).
    #[arg(value_name = "IN")]
    input: PathBuf,
    /// The file to write; the format follows the name: .asc Vector ASC, .blf Vector BLF, .pcapng
    /// pcapng, .mf4 MF4, anything else a candump log.
    #[arg(value_name = "OUT")]
    output: PathBuf,
    /// OUT's format whatever its name says: log (candump), asc, blf, pcapng or mf4.
    #[arg(long, value_name = "FORMAT", value_parser = traces::parse_format)]
    format: Option<FileFormat>,
}

/// What a format keeps of a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Keeps {
    /// Interface names (ASC numbers buses instead).
    pub names: bool,
    /// An error frame's SocketCAN classes and detail bytes (ASC writes `ErrorFrame` alone).
    pub error_details: bool,
    /// "An error frame, no details known" as such (candump and pcapng write the flag with no
    /// class, which reads back as details of zeros).
    pub bare_errors: bool,
    /// Nanoseconds (candump and ASC write microseconds).
    pub nanos: bool,
}

/// What `format` keeps.
pub fn keeps(format: FileFormat) -> Keeps {
    match format {
        FileFormat::Log => Keeps {
            names: true,
            error_details: true,
            bare_errors: false,
            nanos: false,
        },
        FileFormat::Asc => Keeps {
            names: false,
            error_details: false,
            bare_errors: true,
            nanos: false,
        },
        FileFormat::Pcapng => Keeps {
            names: true,
            error_details: true,
            bare_errors: false,
            nanos: true,
        },
        FileFormat::Blf | FileFormat::Mf4 => Keeps {
            names: true,
            error_details: true,
            bare_errors: true,
            nanos: true,
        },
    }
}

/// What went through, and what the target dropped.
#[derive(Debug, Default)]
struct Tally {
    frames: u64,
    errors: u64,
    interfaces: BTreeSet<String>,
    with_details: u64,
    bare: u64,
    sub_micro: u64,
}

/// How often a stop signal is looked for, in records.
const POLL: u64 = 4096;

/// Runs `harvemu convert`.
pub fn run(args: &Args) -> crate::Result<Ended> {
    crate::output::distinct(&[("OUT", Some(&args.output))], &[("IN", &args.input)])?;
    let to = crate::record::format_for(&args.output, args.format);
    let (from, mut items) = traces::open(&args.input, ErrorFrames::Keep)?;
    let first = items.next().transpose()?;
    // Dated at the first record, to the millisecond below it (ASC and BLF date to the ms).
    let start = first
        .as_ref()
        .map_or(Stamp(0), |(_, i)| Stamp(i.at.0 / 1_000_000 * 1_000_000));
    let trace = crate::record::create_items(&args.output, to, start)?;
    let keep = keeps(to);
    let mut tally = Tally::default();
    for r in first.into_iter().map(Ok).chain(items) {
        let (_, item) = r?;
        match item.entry {
            Entry::Frame(_) => tally.frames += 1,
            Entry::Error(Some(_)) => {
                tally.errors += 1;
                tally.with_details += 1;
            }
            Entry::Error(None) => {
                tally.errors += 1;
                tally.bare += 1;
            }
        }
        if item.at.0 % 1000 != 0 {
            tally.sub_micro += 1;
        }
        if !tally.interfaces.contains(&item.interface) {
            tally.interfaces.insert(item.interface.clone());
        }
        trace.write(&item)?;
        if (tally.frames + tally.errors) % POLL == 0
            && let Some(signal) = crate::stop::received()
        {
            // The output is dropped unfinished: its name stays as it was.
            crate::say!(
                "harvemu: convert interrupted by {}: {} left as it was",
                signal.describe(),
                args.output.display()
            );
            return Ok(Ended::default());
        }
    }
    trace.finish(None)?;
    say_what_went(args, from, to, &tally, keep);
    Ok(Ended::default())
}

fn say_what_went(args: &Args, from: FileFormat, to: FileFormat, t: &Tally, keep: Keeps) {
    crate::say!(
        "harvemu: {} ({from}) -> {} ({to}): {} records, {} frames and {} error frames, on {} interface{}",
        args.input.display(),
        args.output.display(),
        t.frames + t.errors,
        t.frames,
        t.errors,
        t.interfaces.len(),
        if t.interfaces.len() == 1 { "" } else { "s" },
    );
    if !keep.error_details && t.with_details > 0 {
        crate::say!(
            "harvemu: {to} keeps no error-frame details: {} error frames are written without their classes, location and counters",
            t.with_details
        );
    }
    if !keep.bare_errors && t.bare > 0 {
        crate::say!(
            "harvemu: {to} has no error frame without details: {} such error frames are written with CAN_ERR_FLAG and no class",
            t.bare
        );
    }
    if !keep.names && t.interfaces.len() > 1 {
        let buses: BTreeSet<&str> = t
            .interfaces
            .iter()
            .map(|i| i.split('.').next().unwrap_or_default())
            .collect();
        let mut names: Vec<&str> = t.interfaces.iter().map(String::as_str).take(4).collect();
        if t.interfaces.len() > names.len() {
            names.push("...");
        }
        crate::say!(
            "harvemu: {to} keeps no interface names: {} interfaces ({}) become {} channel{}, one per bus (the name up to its first dot)",
            t.interfaces.len(),
            names.join(", "),
            buses.len(),
            if buses.len() == 1 { "" } else { "s" },
        );
    }
    if !keep.nanos && t.sub_micro > 0 {
        crate::say!(
            "harvemu: {to} keeps microseconds: {} times are cut to the microsecond",
            t.sub_micro
        );
    }
}
