//! The two C library routines socketcand reads its commands with, so that harvemu reads every
//! command exactly as socketcand does: `sscanf` with a format of the shape
//! `"< %*s %x %hhu %hhx ... >"`, and socketcand's own `element_length`.
//!
//! `sscanf` (glibc) reads each number as `strtoul` would: leading white space skipped, an
//! optional sign, for hex an optional `0x`, then as many digits as there are. The number is then
//! stored into the conversion's type, which truncates it: `%hhx` keeps the low byte of whatever
//! it read (`1FF` gives 0xFF, `100` gives 0), `%x` the low 32 bits. A number too large for 64
//! bits reads as `u64::MAX` (what `strtoul` returns on overflow), and a minus sign negates
//! modulo 2^64 (`-1` is `u64::MAX`, so `%hhx` stores 0xFF). `sscanf` returns how many
//! conversions succeeded before the first that did not: socketcand checks only that count, so
//! whatever follows the last conversion it needs is never looked at.

/// One numeric conversion of a `sscanf` format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Conv {
    /// `%x`, `%hhx`: hex.
    Hex,
    /// `%u`, `%hhu`, `%llu`: decimal.
    Dec,
}

/// C's `isspace`.
pub fn is_space(b: u8) -> bool {
    // C's isspace in the "C" locale (Rust's is_ascii_whitespace leaves out \v).
    matches!(b, b' ' | b'\t' | b'\n' | 0x0b | 0x0c | b'\r')
}

/// `sscanf(text, "< %*s C1 C2 ... >")`: the values of the conversions that succeeded, in order,
/// as `strtoul` gives them (the caller truncates to the conversion's width).
pub fn scan(text: &str, convs: &[Conv]) -> Vec<u64> {
    let s = text.as_bytes();
    let mut out = Vec::with_capacity(convs.len());
    // "<": a literal.
    if s.first() != Some(&b'<') {
        return out;
    }
    let mut i = 1;
    // " %*s": white space, then a run of non-white space, at least one character.
    while i < s.len() && is_space(s[i]) {
        i += 1;
    }
    let word = i;
    while i < s.len() && !is_space(s[i]) {
        i += 1;
    }
    if i == word {
        return out;
    }
    for &conv in convs {
        // The white space between conversions in the format matches any amount, none included;
        // each numeric conversion skips leading white space anyway.
        match number(s, i, conv) {
            Some((v, end)) => {
                out.push(v);
                i = end;
            }
            None => break,
        }
    }
    out
}

/// One `%x` or `%u` at `start`: its value and where it ended.
fn number(s: &[u8], start: usize, conv: Conv) -> Option<(u64, usize)> {
    let mut i = start;
    while i < s.len() && is_space(s[i]) {
        i += 1;
    }
    let negative = match s.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let radix = match conv {
        Conv::Hex => 16,
        Conv::Dec => 10,
    };
    let mut digits = 0usize;
    let mut value: u64 = 0;
    let mut overflow = false;
    if conv == Conv::Hex && s.get(i) == Some(&b'0') && matches!(s.get(i + 1), Some(b'x' | b'X')) {
        // glibc takes the "0" as a digit and the "x" as the prefix; with no hex digit after
        // them the number is the 0 (and the "x" stays consumed).
        digits = 1;
        i += 2;
    }
    while let Some(d) = s.get(i).and_then(|&b| (b as char).to_digit(radix)) {
        match value
            .checked_mul(u64::from(radix))
            .and_then(|v| v.checked_add(u64::from(d)))
        {
            Some(v) => value = v,
            None => overflow = true,
        }
        digits += 1;
        i += 1;
    }
    if digits == 0 {
        return None;
    }
    let value = if overflow {
        u64::MAX
    } else if negative {
        value.wrapping_neg()
    } else {
        value
    };
    Some((value, i))
}

/// socketcand's `element_length(buf, element)`: the length of the `element`-th word of the whole
/// message (`<` is word 0), words being separated by spaces only (a tab is part of a word), a word
/// running to the next space or the end of the message (the closing `>` included).
pub fn element_length(text: &str, element: usize) -> usize {
    let s = text.as_bytes();
    let mut elem = 0;
    let mut i = 0;
    while i < s.len() {
        if s[i] == b' ' {
            elem += 1;
            while i < s.len() && s[i] == b' ' {
                i += 1;
            }
            if i >= s.len() {
                return 0;
            }
        }
        if elem == element {
            return s[i..].iter().take_while(|&&b| b != b' ').count();
        }
        i += 1;
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;
    use Conv::{Dec, Hex};

    #[test]
    fn numbers_read_as_strtoul_reads_them() {
        // (text after the command word, conversions, values glibc's sscanf stores before
        // truncation). Worked out from the C rules by hand.
        let table: &[(&str, &[Conv], &[u64])] = &[
            ("< send 123 2 1 f1 >", &[Hex, Dec, Hex, Hex], &[0x123, 2, 1, 0xF1]),
            (
                "< send 0300A0F5 2 1 1 >",
                &[Hex, Dec, Hex, Hex],
                &[0x0300A0F5, 2, 1, 1],
            ),
            // Three digits and more: the whole number (the caller keeps the low byte).
            (
                "< send 1 2 1FF 100 >",
                &[Hex, Dec, Hex, Hex],
                &[1, 2, 0x1FF, 0x100],
            ),
            // Sign and prefix.
            (
                "< send 0x7ff +2 -1 0X0a >",
                &[Hex, Dec, Hex, Hex],
                &[0x7FF, 2, u64::MAX, 10],
            ),
            // "0x" with no digit after it is 0; the scan goes on after the "x".
            ("< send 0xg >", &[Hex, Hex], &[0]),
            // Numbers need no space between them: "12" then "-3"... and stop at a non-digit.
            ("< send 12-3 >", &[Hex, Hex], &[0x12, 3u64.wrapping_neg()]),
            ("< send 1 2 zz 4 >", &[Hex, Dec, Hex, Hex], &[1, 2]),
            // Overflow saturates.
            ("< send 123456789ABCDEF01 >", &[Hex], &[u64::MAX]),
            ("< send 18446744073709551616 >", &[Dec], &[u64::MAX]),
            // Tabs and newlines are white space to scanf.
            ("<\tsend\t5\n6 >", &[Hex, Hex], &[5, 6]),
            // Nothing after the command word.
            ("< send >", &[Hex], &[]),
            ("< >", &[Hex], &[]),
            ("<send>", &[Hex], &[]),
            ("< send - >", &[Hex], &[]),
            // Decimal stops at a hex letter.
            ("< add 1a >", &[Dec, Dec], &[1]),
        ];
        for (text, convs, want) in table {
            assert_eq!(scan(text, convs), *want, "{text}");
        }
    }

    #[test]
    fn element_lengths_count_spaces_only() {
        assert_eq!(element_length("< send 0300A0F5 2 1 1 >", 2), 8);
        assert_eq!(element_length("< send 123 0 >", 2), 3);
        assert_eq!(element_length("<  send   1AAAAAAA 0 >", 2), 8);
        assert_eq!(element_length("< add 1 0 12345678 0 >", 4), 8);
        // A tab is not a separator; the closing bracket is part of a last word without a space.
        assert_eq!(element_length("< send\t12345678 0 >", 2), 1);
        assert_eq!(element_length("< send 1234567>", 2), 8);
        assert_eq!(element_length("< send >", 3), 0);
        assert_eq!(element_length("< send ", 2), 0);
    }
}
