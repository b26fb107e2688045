//! Reading a scenario: its file, its harvester, and what it takes from the command line.
//!
//! Contract: a [`Loaded`] scenario passed the validation against its harvester and carries its
//! timeline resolved ([`Plan`]), the random faults (drawn as ordinary timeline steps) among it;
//! the seed and the cruise start are applied to it, so that the run needs nothing else.

use super::model::Scenario;
use super::plan::Plan;
use super::random;
use super::validate::{duration_problem, resolve};
use crate::configs::Source;
use crate::harvester::Harvester;
use nodes::Error;
use std::path::Path;

/// A scenario read and checked, with the harvester it runs on.
#[derive(Clone)]
pub struct Loaded {
    /// Its file.
    pub source: Source,
    /// The scenario.
    pub scenario: Scenario,
    /// The harvester, with the scenario's seed applied.
    pub harvester: Harvester,
    /// How many of the timeline's steps are the file's own: the rest were drawn from its
    /// `random_faults`.
    pub fixed: usize,
    /// The scenario resolved: what the run carries out and checks. A change to `scenario`
    /// reaches the run only through [`Loaded::resolved`].
    pub plan: Plan,
}

impl Loaded {
    /// The same scenario with its timeline changed in place (a campaign's drawn faults, a
    /// shrunk history), resolved again; the problems if it no longer resolves.
    pub fn resolved(mut self) -> Result<Loaded, Error> {
        self.plan =
            resolve(&self.source.to_string(), &self.scenario, &self.harvester).map_err(Error::Invalid)?;
        Ok(self)
    }
}

/// Reads and checks a scenario and its harvester; every problem is listed. Files are read with
/// [`Source::read`]: from disk at most [`nodes::file::MAX_FILE`] bytes each, else the built-in
/// copy; the harvester config of a built-in scenario is the built-in one.
pub fn load(path: &Path, seed: Option<u64>) -> Result<Loaded, Error> {
    load_with(path, seed, None, None)
}

/// [`load`], with the run's length replaced by `duration_s` when given (before the random
/// faults are drawn, so that they cover the new length), and the harvester config `config`
/// (a path as on the command line) in place of the one the scenario names, when given.
pub fn load_with(
    path: &Path,
    seed: Option<u64>,
    duration_s: Option<f64>,
    config: Option<&Path>,
) -> Result<Loaded, Error> {
    let (source, text) = Source::file(path).read()?;
    match config {
        Some(c) => parse(&source, &text, seed, duration_s, |_| {
            Harvester::open(&Source::file(c))
        }),
        None => parse(&source, &text, seed, duration_s, Harvester::open),
    }
}

/// As [`load`] with the scenario's text already read: `path` is where it came from (problems
/// name it; its config is relative to its directory) and `harvester` loads the harvester config
/// at a path, as [`Harvester::load`] does.
pub fn from_text(
    path: &Path,
    text: &str,
    seed: Option<u64>,
    harvester: impl FnOnce(&Path) -> Result<Harvester, Error>,
) -> Result<Loaded, Error> {
    parse(&Source::file(path), text, seed, None, |s| harvester(&s.path))
}

/// The problems of the file `file` (text `text`), each with the line and column of the field it
/// names, where the text shows that field.
fn placed(found: Vec<nodes::Problem>, file: &str, text: &str) -> Vec<nodes::Problem> {
    found
        .into_iter()
        .map(|mut p| {
            if p.position.is_none()
                && p.file == file
                && let Some(field) = &p.field
            {
                p.position = nodes::ron_path::position(text, field);
            }
            p
        })
        .collect()
}

fn parse(
    source: &Source,
    text: &str,
    seed: Option<u64>,
    duration_s: Option<f64>,
    harvester: impl FnOnce(&Source) -> Result<Harvester, Error>,
) -> Result<Loaded, Error> {
    let file = source.to_string();
    let mut scenario: Scenario = nodes::parse_ron(&file, text)?;
    if let Some(d) = duration_s {
        scenario.duration_s = d;
    }
    let mut harvester = harvester(&source.beside(&scenario.config))?;
    if let Some(s) = seed.or(scenario.seed) {
        harvester.config.network.seed = s;
    }
    let fixed = scenario.timeline.len();
    let names = harvester.node_names();
    let length = scenario.duration_s;
    if let Some(r) = &scenario.random_faults
        && duration_problem(length).is_none()
        && random::problems(r, length, &names).is_empty()
    {
        // Ordinary steps from here on: the runner, the report and the checks see no difference.
        // (With a problem in the section, or in the length, nothing is drawn: the validation
        // lists the problem.)
        let seed = r.seed.unwrap_or(harvester.config.network.seed);
        scenario.timeline.extend(random::expand(r, seed, length, &names));
    }
    let plan =
        resolve(&file, &scenario, &harvester).map_err(|found| Error::Invalid(placed(found, &file, text)))?;
    if let Some(s) = scenario.cruise_start_s {
        harvester.config.monitor.cruise.start_s = Some(s);
    }
    Ok(Loaded {
        source: source.clone(),
        scenario,
        harvester,
        fixed,
        plan,
    })
}
