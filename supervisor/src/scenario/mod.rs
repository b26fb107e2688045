//! Scenarios: a harvester run in virtual time with a timeline of stimuli and faults, and
//! expectations checked against the monitor's display, the bus statistics and node states, each
//! with a verdict.
//!
//! Contract: [`load()`] gives a scenario only when [`resolve()`] finds no problem in it, with its
//! timeline resolved ([`Plan`]), and lists every problem otherwise; [`run()`] plays a loaded scenario to an [`Outcome`] with one verdict per
//! expectation, the same for the same seed. A step the running harvester cannot carry out (a
//! fault the node's logic refuses) ends the run with an error naming the step, node and fault.
//!
//! The parts: the file format (`model`), reading (`load`), validation and resolution
//! (`validate`, into the [`Plan`] of `plan`), the run
//! loop (`run`), the timeline's actions on the running harvester
//! (`actions`, with the babbling idiot in `babbler`), the verdicts (`check`, over the node
//! states of `states`), and what the run leaves for the report ([`books`], [`series`],
//! [`trace_count`], [`junit`]); [`random`] draws random faults as ordinary timeline steps.

mod actions;
mod babbler;
pub mod books;
mod check;
pub mod junit;
mod kinds;
mod load;
mod model;
mod plan;
pub mod random;
mod run;
pub mod series;
mod states;
pub mod trace_count;
mod validate;

pub(crate) use actions::Actions;
pub use check::Verdict;
pub use check::all as check_all;
pub use load::{Loaded, from_text, load, load_with};
pub use model::*;
pub use plan::{Act, Check, Plan, Todo};
pub use random::{Fault, Hit, RandomFault, RandomFaults};
pub use run::{Outcome, run};
pub use series::Series;
pub use validate::{
    MAX_DURATION_S, MAX_OVERLOAD_FRAMES, action as resolve_action, expectations as resolve_expectations,
    resolve, validate,
};
