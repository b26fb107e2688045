//! The terminal glue of `harvemu run --tui`: it runs the harvester in steps, redraws and reads
//! keys; everything it shows comes from [`View::build`] and [`draw`].
//!
//! Contract: the terminal is left in the state it was found in on every way out: a normal end,
//! an error (the [`Restore`] guard) and a panic (ratatui's panic hook restores it before the
//! panic message is printed).

use super::{Clock, RateMeter, Sources, View, draw, quits};
use crate::Error;
use crate::harvester::Running;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::GetSnapshot;
use ratatui::DefaultTerminal;
use ratatui::crossterm::event::{self, Event};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Bus time run between two looks at the keyboard (and at the wall clock for a redraw), in real
/// time and in virtual time: virtual time runs tens of times faster than the wall clock, and
/// looking costs a little each time.
const STEP_MS: u64 = 50;
const FAST_STEP_MS: u64 = 500;
/// Wall time between redraws.
const REFRESH: Duration = Duration::from_millis(250);

/// Refuses `--tui` when standard output is not a terminal (a pipe or a file).
pub fn require_terminal() -> crate::Result<()> {
    if std::io::stdout().is_terminal() {
        Ok(())
    } else {
        Err(Error::BadInput(
            "--tui needs a terminal, and standard output is not one (leave out --tui to get a summary line)"
                .into(),
        ))
    }
}

/// Restores the terminal when dropped, also when setting it up failed halfway.
struct Restore;

impl Drop for Restore {
    fn drop(&mut self) {
        ratatui::restore();
    }
}

/// What the keyboard asked for since the last look.
#[derive(PartialEq)]
enum Input {
    Nothing,
    Redraw,
    Quit,
}

/// Reads every key and resize waiting, without blocking longer than `wait`.
fn input(wait: Duration) -> std::io::Result<Input> {
    let mut got = Input::Nothing;
    let mut wait = wait;
    while event::poll(wait)? {
        wait = Duration::ZERO;
        match event::read()? {
            Event::Key(key) if quits(&key) => return Ok(Input::Quit),
            Event::Resize(..) => got = Input::Redraw,
            _ => {}
        }
    }
    Ok(got)
}

/// Shows the running harvester until `q`, Esc or Ctrl-C. With an `end`, the run stops there and
/// the final state stays on screen until a quit key.
pub async fn live(
    running: &mut Running,
    machine: &str,
    fast: bool,
    end: Option<BusTime>,
) -> crate::Result<()> {
    let _restore = Restore;
    let mut terminal = ratatui::try_init().map_err(Error::System)?;
    let clock = if fast { Clock::Virtual } else { Clock::RealTime };
    let mut rates = RateMeter::default();
    let mut last_draw: Option<Instant> = None;
    let step = BusDuration::from_millis(if fast { FAST_STEP_MS } else { STEP_MS });
    let mut stop = crate::stop::Stop::new().map_err(Error::System)?;
    while end.is_none_or(|e| running.now() < e) {
        let t = running.now();
        let next = t.next_multiple_of(step);
        let next = end.map_or(next, |e| next.min(e));
        tokio::select! {
            r = running.run_until(next) => r?,
            // A signal from outside (the keyboard's Ctrl-C arrives as a key in raw mode).
            _ = stop.wait() => return Ok(()),
        }
        let asked = input(Duration::ZERO).map_err(Error::System)?;
        if asked == Input::Quit {
            return Ok(());
        }
        if asked == Input::Redraw || last_draw.is_none_or(|d| d.elapsed() >= REFRESH) {
            redraw(&mut terminal, running, &mut rates, machine, clock, false).await?;
            last_draw = Some(Instant::now());
        }
    }
    redraw(&mut terminal, running, &mut rates, machine, clock, true).await?;
    while crate::stop::received().is_none() {
        // The run is over and the hub idle: waiting on the keyboard blocks nothing that matters
        // in virtual time; in real time a socketcand client or a bridge may still be served, so
        // the runtime gets to run between short looks.
        let asked = if fast {
            input(REFRESH).map_err(Error::System)?
        } else {
            tokio::time::sleep(Duration::from_millis(STEP_MS)).await;
            input(Duration::ZERO).map_err(Error::System)?
        };
        match asked {
            Input::Quit => return Ok(()),
            Input::Redraw => redraw(&mut terminal, running, &mut rates, machine, clock, true).await?,
            Input::Nothing => {}
        }
    }
    Ok(())
}

async fn redraw(
    terminal: &mut DefaultTerminal,
    running: &Running,
    rates: &mut RateMeter,
    machine: &str,
    clock: Clock,
    finished: bool,
) -> crate::Result<()> {
    let snapshot = running.hub.send(GetSnapshot).await?;
    rates.update(&snapshot);
    let display = running.display.as_ref().map(|d| d.borrow());
    let plant = running.plant.borrow();
    let view = View::build(&Sources {
        machine,
        clock,
        finished,
        snapshot: &snapshot,
        display: display.as_deref(),
        plant: &plant,
        rates,
        events: &running.events,
        database: running.database(),
    });
    terminal.draw(|frame| draw(frame, &view)).map_err(Error::System)?;
    Ok(())
}
