//! What `harvemu run` writes to stderr while it runs, laid out for where stderr goes.
//!
//! - A terminal, in real time: one status line redrawn in place (`\r`, the line, clear to its
//!   end), never wider than the terminal ([`Summary::fit`]), so it neither wraps nor scrolls.
//! - A terminal, in virtual time (`--fast`, which always has an end): indicatif's bar with the
//!   fitted summary on a line under it.
//! - Anything else (a pipe, a log file): plain lines, each ending in a newline, one every
//!   [`PLAIN_EVERY`] of bus time, or every sixtieth of the run when that is longer
//!   ([`plain_period`]), so that a log holds at most about [`PLAIN_LINES`] of them.
//!
//! Events (crashes, restarts) get lines of their own in every mode. [`Console::finish`] clears
//! the live line and prints the closing summary once, also after Ctrl-C: in a terminal wrapped
//! to its width, elsewhere on one line.

use super::summary::Summary;
use bus::time::BusTime;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{IsTerminal, Write};

/// The shortest time between two plain lines [bus time]: often enough to see a run move in a
/// log, rare enough that a minute of it is six lines.
pub const PLAIN_EVERY: BusTime = BusTime::from_secs(10);

/// About how many plain lines a run with an end prints at most.
pub const PLAIN_LINES: u64 = 60;

/// Width assumed when a terminal does not say its own.
const DEFAULT_WIDTH: usize = 80;

/// Carriage return, then ANSI "erase to end of line": what redraws a line in place.
const REDRAW: &str = "\r\x1b[K";

/// The time between plain lines for a run that ends at `end`: [`PLAIN_EVERY`], or the run's
/// length over [`PLAIN_LINES`] rounded up to a multiple of it.
pub fn plain_period(end: Option<BusTime>) -> BusTime {
    let share = end.map_or(0, |e| e.as_ticks().div_ceil(PLAIN_LINES));
    BusTime::from_ticks(share)
        .ceil_to(PLAIN_EVERY.elapsed())
        .max(PLAIN_EVERY)
}

/// The width of the terminal on stderr (the whole line must stay left of its last column,
/// where some terminals wrap).
fn terminal_width() -> usize {
    ratatui::crossterm::terminal::size()
        .map(|(w, _)| usize::from(w))
        .ok()
        .filter(|w| *w > 0)
        .unwrap_or(DEFAULT_WIDTH)
}

enum Mode {
    /// One line redrawn in place, fitted to `width() - 1`.
    Line { width: fn() -> usize, drawn: bool },
    /// indicatif's bar; the fitted summary is its message.
    Bar { bar: ProgressBar, width: fn() -> usize },
    /// A plain line whenever bus time passes `next`, except at `end` (the closing summary says
    /// it then).
    Plain {
        every: BusTime,
        next: BusTime,
        end: Option<BusTime>,
    },
}

/// The live output of a run.
pub struct Console<W: Write> {
    out: W,
    mode: Mode,
}

impl Console<std::io::Stderr> {
    /// The console for stderr: a live line or bar when it is a terminal, plain lines otherwise.
    pub fn stderr(fast: bool, end: Option<BusTime>) -> Self {
        let out = std::io::stderr();
        if !out.is_terminal() {
            return Console::plain(out, end);
        }
        match end {
            Some(end) if fast => {
                let bar = ProgressBar::new(end.as_secs());
                bar.set_style(
                    ProgressStyle::with_template("{wide_bar} {pos}/{len} s virtual, {elapsed} wall\n{msg}")
                        .unwrap_or_else(|_| ProgressStyle::default_bar()),
                );
                Console {
                    out,
                    mode: Mode::Bar {
                        bar,
                        width: terminal_width,
                    },
                }
            }
            _ => Console::line(out, terminal_width),
        }
    }
}

impl<W: Write> Console<W> {
    /// Plain lines to `out`, for a run that ends at `end`.
    pub fn plain(out: W, end: Option<BusTime>) -> Self {
        let every = plain_period(end);
        Console {
            out,
            mode: Mode::Plain {
                every,
                next: every,
                end,
            },
        }
    }

    /// One line redrawn in place on `out`, a terminal `width()` columns wide.
    pub fn line(out: W, width: fn() -> usize) -> Self {
        Console {
            out,
            mode: Mode::Line { width, drawn: false },
        }
    }

    /// Shows the run's state at `s.at` (called about once a second of bus time).
    pub fn update(&mut self, s: &Summary) {
        match &mut self.mode {
            Mode::Line { width, drawn } => {
                let _ = write!(self.out, "{REDRAW}{}", s.fit(width().saturating_sub(1)));
                let _ = self.out.flush();
                *drawn = true;
            }
            Mode::Bar { bar, width } => {
                bar.set_position(s.at.as_secs());
                bar.set_message(s.fit(width().saturating_sub(1)));
            }
            Mode::Plain { every, next, end } => {
                if s.at >= *next && end.is_none_or(|e| s.at < e) {
                    let _ = writeln!(self.out, "{s}");
                    let _ = self.out.flush();
                }
                if s.at >= *next {
                    *next = s.at.next_multiple_of(every.elapsed());
                }
            }
        }
    }

    /// Prints `text` on a line of its own, above the live line.
    pub fn event(&mut self, text: &str) {
        match &mut self.mode {
            Mode::Line { drawn, .. } => {
                if *drawn {
                    let _ = write!(self.out, "{REDRAW}");
                    *drawn = false;
                }
                let _ = writeln!(self.out, "{text}");
            }
            Mode::Bar { bar, .. } => bar.suspend(|| {
                let _ = writeln!(self.out, "{text}");
            }),
            Mode::Plain { .. } => {
                let _ = writeln!(self.out, "{text}");
            }
        }
        let _ = self.out.flush();
    }

    /// Clears the live line or bar, says so when the run was interrupted, and prints the closing
    /// summary once. Returns the output.
    pub fn finish(mut self, s: &Summary, interrupted: Option<crate::stop::Signal>) -> W {
        let width = match &self.mode {
            Mode::Line { width, drawn } => {
                if *drawn {
                    let _ = write!(self.out, "{REDRAW}");
                }
                Some(width())
            }
            Mode::Bar { bar, width } => {
                bar.finish_and_clear();
                Some(width())
            }
            Mode::Plain { .. } => None,
        };
        if let Some(signal) = interrupted {
            let _ = writeln!(self.out, "harvemu: interrupted by {}", signal.describe());
        }
        match width {
            Some(w) => {
                for line in s.wrap(w.saturating_sub(1)) {
                    let _ = writeln!(self.out, "{line}");
                }
            }
            None => {
                let _ = writeln!(self.out, "{s}");
            }
        }
        let _ = self.out.flush();
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(secs: u64) -> Summary {
        Summary {
            at: BusTime::from_secs(secs),
            frames: secs * 2000,
            load: 0.31,
            load_1s: 0.32,
            error_frames: 0,
            not_active: 0,
            speed_kmh: 4.5,
            harvested_kg: secs as f64 * 0.8,
            plant: true,
            basket_pct: 3.0,
            monitor: None,
        }
    }

    #[test]
    fn the_plain_period_is_ten_seconds_or_a_sixtieth_of_the_run() {
        assert_eq!(plain_period(None), BusTime::from_secs(10));
        assert_eq!(plain_period(Some(BusTime::from_secs(30))), BusTime::from_secs(10));
        assert_eq!(
            plain_period(Some(BusTime::from_secs(600))),
            BusTime::from_secs(10)
        );
        assert_eq!(
            plain_period(Some(BusTime::from_secs(601))),
            BusTime::from_secs(20)
        );
        assert_eq!(
            plain_period(Some(BusTime::from_secs(3600))),
            BusTime::from_secs(60)
        );
        assert_eq!(
            plain_period(Some(BusTime::from_secs(86_400))),
            BusTime::from_secs(1440)
        );
    }

    #[test]
    fn plain_lines_come_at_each_period_and_the_summary_once_at_the_end() {
        let mut c = Console::plain(Vec::new(), Some(BusTime::from_secs(30)));
        for t in 1..=30 {
            c.update(&at(t));
            if t == 15 {
                c.event("harvemu: 15.000000 D3 crashed");
            }
        }
        let text = String::from_utf8(c.finish(&at(30), None)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert!(lines[0].starts_with("t=10.0 s  "), "{text}");
        assert_eq!(lines[1], "harvemu: 15.000000 D3 crashed");
        assert!(lines[2].starts_with("t=20.0 s  "), "{text}");
        assert_eq!(lines[3], at(30).to_string());
        assert!(!text.contains('\r') && !text.contains('\x1b'), "{text:?}");
    }

    #[test]
    fn a_long_plain_run_prints_about_sixty_lines() {
        let mut c = Console::plain(Vec::new(), Some(BusTime::from_secs(1200)));
        for t in 1..=1200 {
            c.update(&at(t));
        }
        let text = String::from_utf8(c.finish(&at(1200), None)).unwrap();
        let want: Vec<String> = (1..=60).map(|i| at(i * 20).to_string()).collect();
        assert_eq!(text.lines().collect::<Vec<_>>(), want);
    }

    #[test]
    fn an_interrupted_plain_run_says_so_and_sums_up_once() {
        let mut c = Console::plain(Vec::new(), None);
        for t in 1..=12 {
            c.update(&at(t));
        }
        let text = String::from_utf8(c.finish(&at(12), Some(crate::stop::Signal::Int))).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            [
                at(10).to_string().as_str(),
                "harvemu: interrupted by SIGINT (Ctrl-C)",
                at(12).to_string().as_str()
            ]
        );
    }

    #[test]
    fn the_terminal_line_is_redrawn_within_the_width_and_cleared_at_the_end() {
        fn sixty() -> usize {
            60
        }
        let mut c = Console::line(Vec::new(), sixty);
        for t in 1..=5 {
            c.update(&at(t));
        }
        c.event("harvemu: 5.000000 D3 crashed");
        c.update(&at(6));
        let text = String::from_utf8(c.finish(&at(6), Some(crate::stop::Signal::Int))).unwrap();
        // Every redraw, between two REDRAWs, is shorter than the terminal.
        let draws: Vec<&str> = text.split(REDRAW).collect();
        for d in &draws[..draws.len() - 1] {
            assert!(!d.contains('\n') || d.ends_with('\n'), "{d:?}");
            assert!(d.trim_end_matches('\n').len() < 60, "{d:?}");
        }
        assert!(
            draws[1].starts_with("t=1.0 s  load 31.0%  not active 0  harvested 0.8 kg"),
            "{text:?}"
        );
        // After the last redraw only whole lines: the interruption, the summary once.
        let tail = draws.last().unwrap();
        let lines: Vec<&str> = tail.lines().collect();
        assert_eq!(lines[0], "harvemu: interrupted by SIGINT (Ctrl-C)", "{tail:?}");
        assert_eq!(lines[1..].join("  "), at(6).to_string());
        assert!(lines.iter().all(|l| l.len() < 60), "{tail:?}");
        assert_eq!(text.matches("harvemu: 5.000000 D3 crashed\n").count(), 1);
    }
}
