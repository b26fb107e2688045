//! `harvemu dbc`: a DBC of the whole harvester, from the message catalogue and the cycle times of
//! the harvester config's node scripts; or, for a network imported from a DBC (`harvemu
//! import`), of its database with the cycle times its scripts send. `-o FILE` gets the whole DBC or, when it cannot be
//! written completely, is left as it was (exit code 3).

use crate::harvester::Harvester;
use nodes::script::When;
use protocol::catalogue::dbc::{self, Network};
use protocol::catalogue::{MESSAGES, Trigger};
use protocol::ident::Address;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `harvemu dbc`.
#[derive(clap::Args)]
pub struct Args {
    /// Write the DBC to this file instead of standard output.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Harvester config (or network config from `harvemu import`) whose node scripts give the
    /// cycle times.
    /// The default is read from the working directory when it is there, else built in.
    #[arg(long, value_name = "FILE", default_value = "configs/harvester.ron")]
    config: PathBuf,
}

/// The network `h` describes: each scripted node's periodic and on-change messages, with the
/// shortest cycle when a script sends a message from more than one entry.
pub fn network(h: &Harvester) -> Network {
    let mut scripted: BTreeMap<Address, BTreeMap<String, Trigger>> = BTreeMap::new();
    for script in &h.scripts {
        let sends = scripted.entry(Address(script.address)).or_default();
        for send in &script.messages {
            let trigger = match send.when {
                When::Periodic { period_ms, .. } => Trigger::Periodic {
                    period_ms: u32::try_from(period_ms).unwrap_or(u32::MAX),
                },
                When::OnChange { heartbeat_ms, .. } => Trigger::OnChange {
                    heartbeat_ms: u32::try_from(heartbeat_ms).unwrap_or(u32::MAX),
                },
                When::OnRequest => continue,
            };
            for frame in &send.frames {
                let shorter = match sends.get(&frame.message).and_then(|t| t.cycle_ms()) {
                    Some(known) => trigger.cycle_ms().is_some_and(|new| new < known),
                    None => true,
                };
                if shorter {
                    sends.insert(frame.message.clone(), trigger);
                }
            }
        }
    }
    Network {
        name: h.config.network.name.clone(),
        bitrate: h.config.network.bitrate,
        scripted,
    }
}

/// The database of a network imported from a DBC file (its scripts name one), `None` for the
/// harvester. Scripts that name different databases, or some one and some none, cannot make one
/// DBC: bad input.
fn database(h: &Harvester) -> crate::Result<Option<std::sync::Arc<protocol::database::Database>>> {
    let mut found: Option<(&str, &std::sync::Arc<protocol::database::Database>)> = None;
    let mut plain = None;
    for s in &h.scripts {
        match (&s.db, found) {
            (None, _) => plain = Some(&s.name),
            (Some(db), None) => found = Some((&s.name, db)),
            (Some(db), Some((first, known))) if **db != **known => {
                return Err(crate::Error::BadInput(format!(
                    "{}: nodes {first} and {} name different DBC files: no one DBC describes the network",
                    h.source, s.name
                )));
            }
            _ => {}
        }
    }
    match (found, plain) {
        (Some((with, _)), Some(without)) => Err(crate::Error::BadInput(format!(
            "{}: node {with} sends a DBC file's messages and node {without} the harvester's: no one DBC describes the network",
            h.source
        ))),
        (found, _) => Ok(found.map(|(_, db)| std::sync::Arc::clone(db))),
    }
}

/// The cycle time of each message the network's scripts send on their own (periodic: the
/// period; on change: the heartbeat), the shortest where several entries send it.
fn cycles(h: &Harvester) -> BTreeMap<String, u32> {
    let mut out: BTreeMap<String, u32> = BTreeMap::new();
    for script in &h.scripts {
        for send in script.messages.iter().filter(|m| m.enabled) {
            let ms = match send.when {
                When::Periodic { period_ms, .. } => period_ms,
                When::OnChange { heartbeat_ms, .. } => heartbeat_ms,
                When::OnRequest => continue,
            };
            let ms = u32::try_from(ms).unwrap_or(u32::MAX);
            for frame in &send.frames {
                let c = out.entry(frame.message.clone()).or_insert(ms);
                *c = (*c).min(ms);
            }
        }
    }
    out
}

/// Runs `harvemu dbc`.
pub fn run(args: &Args) -> crate::Result<()> {
    crate::output::distinct(
        &[("--output", args.output.as_deref())],
        &[("--config", &args.config)],
    )?;
    let h = Harvester::load(&args.config)?;
    let text = match database(&h)? {
        Some(db) => db.to_dbc(&protocol::database::Written {
            name: &h.config.network.name,
            bitrate: h.config.network.bitrate,
            cycles: &cycles(&h),
        }),
        None => dbc::generate(MESSAGES, &network(&h)),
    };
    match &args.output {
        Some(path) => crate::output::write_whole(path, text.as_bytes())?,
        None => crate::output::stdout(&text)?,
    }
    Ok(())
}
