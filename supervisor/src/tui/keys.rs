//! Which keys end the live display.
//!
//! Contract: [`quits`] is true for a press (or repeat) of `q`, Esc or Ctrl-C. In raw mode the
//! terminal does not turn Ctrl-C into a signal, so it arrives here as a key like any other.

use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};

/// True when `key` asks the display to quit.
pub fn quits(key: &KeyEvent) -> bool {
    if key.kind == KeyEventKind::Release {
        return false;
    }
    match key.code {
        KeyCode::Char('q' | 'Q') | KeyCode::Esc => true,
        KeyCode::Char('c' | 'C') => key.modifiers.contains(KeyModifiers::CONTROL),
        _ => false,
    }
}
