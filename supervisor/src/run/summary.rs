//! The summary of a running harvester, as `run` and `replay` report it: gathered once as numbers
//! ([`Summary::of`]) and laid out at the edge in one of three ways:
//!
//! - [`Summary`]'s `Display`: every field on one line, for pipes, log files and closing lines;
//! - [`Summary::fit`]: one line of at most a given width, for a line redrawn in a terminal. Fields
//!   are left out whole, least important first ([`Field::rank`]); a number is never cut;
//! - [`Summary::wrap`]: every field, on as many lines of at most a given width as it takes.

use crate::harvester::Running;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Snapshot;

/// What the summary says, as numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Bus time.
    pub at: BusTime,
    /// Frames on the bus since the start.
    pub frames: u64,
    /// Bus load since the start [fraction of the bit time, 0..1].
    pub load: f64,
    /// Bus load over the last second [0..1].
    pub load_1s: f64,
    /// Error frames since the start.
    pub error_frames: u64,
    /// Nodes that are not error active (error passive or bus off).
    pub not_active: usize,
    /// The plant's travel speed [km/h].
    pub speed_kmh: f64,
    /// Cotton harvested, the plant's truth [kg].
    pub harvested_kg: f64,
    /// The plant's fields (speed, harvest, basket) mean something: a harvester, not a plain
    /// network.
    pub plant: bool,
    /// Basket fill [%].
    pub basket_pct: f64,
    /// What the monitor shows, when there is one.
    pub monitor: Option<MonitorSummary>,
}

/// What the reference monitor shows.
#[derive(Clone, Debug, PartialEq)]
pub struct MonitorSummary {
    /// Its total yield [kg].
    pub total_kg: f64,
    /// Its active alarms.
    pub alarms: usize,
    /// The nodes among them with a "missing" alarm: expected, never heard.
    pub missing: Vec<String>,
}

/// One field of the laid-out summary: its text and how important it is (0 most).
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Lower ranks are kept longer when the line must be shortened.
    pub rank: u8,
    /// The field as shown, label and number (`frames 12345`).
    pub text: String,
}

/// Between two fields on a line.
const SEPARATOR: &str = "  ";

impl Summary {
    /// The summary of a running harvester from a snapshot of its hub.
    pub fn of(s: &Snapshot, running: &Running) -> Summary {
        let p = running.plant.borrow();
        let get = |n: &str| p.signal(n).unwrap_or(f64::NAN);
        Summary {
            at: s.now,
            frames: s.stats.frames,
            load: s.stats.total_load(),
            load_1s: s.stats.window_load(BusDuration::from_secs(1)),
            error_frames: s.stats.error_frames,
            not_active: s
                .nodes
                .iter()
                .filter(|n| n.state != bus::fault::ErrorState::Active)
                .count(),
            speed_kmh: get("speed.actual"),
            harvested_kg: get("harvested.total"),
            plant: !running.harvester().network,
            basket_pct: get("basket.fill"),
            monitor: running.display.as_ref().map(|d| {
                let d = d.borrow();
                // The config's name of each node, where the monitor knows only its address.
                let name = |node: &str| {
                    let expected = &running.harvester().expected;
                    expected
                        .iter()
                        .find(|(_, a, _)| a.to_string() == node)
                        .map_or(node.to_string(), |(n, _, _)| n.clone())
                };
                MonitorSummary {
                    total_kg: d.total_kg,
                    alarms: d.active_alarms().count(),
                    missing: d
                        .active_alarms()
                        .filter(|a| a.name == "missing")
                        .map(|a| name(&a.node))
                        .collect(),
                }
            }),
        }
    }

    /// The fields in the order they are shown. The ranks put first what says whether the run is
    /// healthy and what it produced: time, harvest, nodes in trouble, alarms, load, errors.
    pub fn fields(&self) -> Vec<Field> {
        let field = |rank, text| Field { rank, text };
        let mut fields = vec![
            field(0, format!("t={:.1} s", self.at.as_secs_f64())),
            field(7, format!("frames {}", self.frames)),
            field(4, format!("load {:.1}%", self.load * 100.0)),
            field(10, format!("(1 s {:.1}%)", self.load_1s * 100.0)),
            field(5, format!("errors {}", self.error_frames)),
            field(2, format!("not active {}", self.not_active)),
        ];
        if self.plant {
            fields.push(field(6, format!("speed {:.1} km/h", self.speed_kmh)));
            fields.push(field(1, format!("harvested {:.1} kg", self.harvested_kg)));
            fields.push(field(9, format!("basket {:.1}%", self.basket_pct)));
        }
        if let Some(m) = &self.monitor {
            fields.push(field(8, format!("monitor {:.1} kg", m.total_kg)));
            let missing = if m.missing.is_empty() {
                String::new()
            } else {
                format!(" (missing {})", m.missing.join(" "))
            };
            let s = if m.alarms == 1 { "" } else { "s" };
            fields.push(field(3, format!("{} alarm{s}{missing}", m.alarms)));
        }
        fields
    }

    /// One line of at most `width` characters: the most important fields that fit, in their
    /// usual order. Empty when not even the bus time fits.
    pub fn fit(&self, width: usize) -> String {
        let fields = self.fields();
        let mut by_rank: Vec<usize> = (0..fields.len()).collect();
        by_rank.sort_by_key(|&i| fields[i].rank);
        let mut keep = vec![false; fields.len()];
        let mut used = 0;
        for i in by_rank {
            let cost = fields[i].text.len() + if used == 0 { 0 } else { SEPARATOR.len() };
            if used + cost > width {
                // Strictly by importance: a less important field never takes the place of a
                // more important one that did not fit.
                break;
            }
            used += cost;
            keep[i] = true;
        }
        let kept: Vec<&str> = fields
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(f, _)| f.text.as_str())
            .collect();
        kept.join(SEPARATOR)
    }

    /// Every field, in order, on lines of at most `width` characters (a field longer than
    /// `width` gets a line of its own).
    pub fn wrap(&self, width: usize) -> Vec<String> {
        let mut lines: Vec<String> = Vec::new();
        for f in self.fields() {
            match lines.last_mut() {
                Some(line) if line.len() + SEPARATOR.len() + f.text.len() <= width => {
                    line.push_str(SEPARATOR);
                    line.push_str(&f.text);
                }
                _ => lines.push(f.text),
            }
        }
        lines
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let texts: Vec<String> = self.fields().into_iter().map(|f| f.text).collect();
        f.write_str(&texts.join(SEPARATOR))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> Summary {
        Summary {
            at: BusTime::from_millis(3_723_400),
            frames: 12_345_678,
            load: 0.4567,
            load_1s: 0.5,
            error_frames: 3,
            not_active: 1,
            speed_kmh: 5.26,
            harvested_kg: 1234.56,
            plant: true,
            basket_pct: 42.0,
            monitor: Some(MonitorSummary {
                total_kg: 1230.0,
                alarms: 2,
                missing: vec!["D3".into()],
            }),
        }
    }

    #[test]
    fn the_full_line_has_every_field() {
        assert_eq!(
            example().to_string(),
            "t=3723.4 s  frames 12345678  load 45.7%  (1 s 50.0%)  errors 3  not active 1  \
             speed 5.3 km/h  harvested 1234.6 kg  basket 42.0%  monitor 1230.0 kg  2 alarms (missing D3)"
        );
    }

    #[test]
    fn a_fitted_line_is_never_wider_than_asked_and_keeps_whole_fields() {
        let s = example();
        let fields: Vec<String> = s.fields().into_iter().map(|f| f.text).collect();
        for width in 0..=200 {
            let line = s.fit(width);
            assert!(line.len() <= width, "{width}: {line:?}");
            // Each piece is one field exactly as the full line has it: no number is cut.
            if !line.is_empty() {
                for piece in line.split(SEPARATOR) {
                    assert!(fields.iter().any(|f| f == piece), "{width}: {piece:?}");
                }
            }
        }
        assert_eq!(s.fit(9), "");
        assert_eq!(s.fit(10), "t=3723.4 s");
        assert_eq!(s.fit(31), "t=3723.4 s  harvested 1234.6 kg");
        assert_eq!(s.fit(200), s.to_string());
    }

    #[test]
    fn fields_are_left_out_least_important_first() {
        let s = example();
        let fields = s.fields();
        let mut shown_before = fields.len() + 1;
        for width in (0..=200).rev() {
            let line = s.fit(width);
            let shown: Vec<&Field> = fields
                .iter()
                .filter(|f| line.split(SEPARATOR).any(|p| p == f.text))
                .collect();
            assert!(shown.len() <= shown_before);
            shown_before = shown.len();
            // What is shown are the most important fields.
            let worst_shown = shown.iter().map(|f| f.rank).max();
            let best_hidden = fields
                .iter()
                .filter(|f| !shown.iter().any(|g| g.text == f.text))
                .map(|f| f.rank)
                .min();
            if let (Some(w), Some(b)) = (worst_shown, best_hidden) {
                assert!(w < b, "{width}: {line:?}");
            }
        }
    }

    #[test]
    fn wrapped_lines_hold_every_field_within_the_width() {
        let s = example();
        for width in [40, 60, 80] {
            let lines = s.wrap(width);
            assert!(lines.iter().all(|l| l.len() <= width), "{lines:?}");
            assert_eq!(lines.join(SEPARATOR), s.to_string());
        }
        assert_eq!(s.wrap(500), [s.to_string()]);
    }
}
