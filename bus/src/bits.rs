//! The exact bitstream of a classic CAN frame, and how long it lasts on the wire.
//!
//! [`encode`] lays a frame out field by field (docs/CAN.md, section 1), computes the CRC-15
//! over the unstuffed bits from SOF to the end of the data field, and stuffs SOF through the last
//! CRC bit. [`Encoded::total_bits`] adds the fixed tail (CRC delimiter, ACK slot and delimiter,
//! 7 EOF bits, 3 intermission bits), which is what a frame costs the bus. The can-utils estimates
//! ([`worst_case_bits`], [`no_stuffing_bits`]) are given beside it because other tools report
//! them.
//!
//! The hub calls [`frame_bits`] once per frame, so it avoids allocation: the unstuffed frame fits
//! in a `u128` (at most 118 bits) and the stuffed one in three words.

use crate::Frame;
use crate::time::BusDuration;
use crc::{CRC_15_CAN, Crc};
use embedded_can::Id;

/// CRC delimiter, ACK slot, ACK delimiter, 7 EOF bits, 3 intermission bits.
pub const TAIL_BITS: u32 = 3 + 7 + 3;

const CAN_CRC: Crc<u16> = Crc::<u16>::new(&CRC_15_CAN);

/// A sequence of up to 192 bits, first bit first.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct BitStream {
    words: [u64; 3],
    len: u8,
}

impl BitStream {
    /// Capacity in bits.
    pub const CAPACITY: usize = 192;

    fn push(&mut self, bit: bool) {
        let i = usize::from(self.len);
        // Callers never exceed 147 bits (118 stuffed with at most 29 stuff bits).
        if i < Self::CAPACITY {
            if bit {
                self.words[i / 64] |= 1 << (63 - i % 64);
            }
            self.len += 1;
        }
    }

    /// Number of bits.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True when there are no bits.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bit `i` (true = recessive 1), or `None` past the end.
    pub fn get(&self, i: usize) -> Option<bool> {
        (i < self.len()).then(|| self.words[i / 64] >> (63 - i % 64) & 1 == 1)
    }

    /// The bits in order.
    pub fn iter(&self) -> impl Iterator<Item = bool> + '_ {
        (0..self.len()).map(|i| self.words[i / 64] >> (63 - i % 64) & 1 == 1)
    }
}

impl core::fmt::Display for BitStream {
    /// `0` for dominant, `1` for recessive, as docs/CAN.md writes bitstreams.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for bit in self.iter() {
            f.write_str(if bit { "1" } else { "0" })?;
        }
        Ok(())
    }
}

impl core::fmt::Debug for BitStream {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "BitStream({self})")
    }
}

/// A frame as it goes on the wire.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Encoded {
    /// SOF through the last CRC bit, stuffed.
    pub stuffed: BitStream,
    /// The CRC-15 sequence.
    pub crc: u16,
    /// Stuff bits inserted.
    pub stuff_bits: u32,
}

impl Encoded {
    /// Every bit the frame occupies the bus for, including the 3 intermission bits.
    pub fn total_bits(&self) -> u32 {
        self.stuffed.len() as u32 + TAIL_BITS
    }
}

/// Bits of SOF..end of data, unstuffed and without CRC, as a right-aligned number and a length.
fn unstuffed_head(frame: &Frame) -> (u128, u32) {
    let mut v: u128 = 0;
    let mut n: u32 = 0;
    let mut put = |value: u128, width: u32| {
        v = (v << width) | (value & ((1u128 << width) - 1));
        n += width;
    };
    let rtr = u128::from(frame.is_remote());
    put(0, 1); // SOF
    match frame.id() {
        Id::Standard(id) => {
            put(u128::from(id.as_raw()), 11);
            put(rtr, 1);
            put(0, 1); // IDE dominant
            put(0, 1); // r0
        }
        Id::Extended(id) => {
            let raw = u128::from(id.as_raw());
            put(raw >> 18, 11);
            put(1, 1); // SRR recessive
            put(1, 1); // IDE recessive
            put(raw, 18);
            put(rtr, 1);
            put(0, 2); // r1, r0
        }
    }
    put(u128::from(frame.dlc()), 4);
    for &byte in frame.data() {
        put(u128::from(byte), 8);
    }
    (v, n)
}

/// Where a node sending `own` loses arbitration to `winner`: the first bit after SOF at which
/// `own` is recessive and `winner` dominant, numbered from 0 at the first identifier bit (the
/// SJA1000's ALC numbering: SRR, IDE and RTR count as bits of the arbitration field). `None`
/// when `own` does not lose to `winner` before their arbitration fields end.
pub fn arbitration_lost_at(own: &Frame, winner: &Frame) -> Option<u16> {
    let (a, la) = unstuffed_head(own);
    let (b, lb) = unstuffed_head(winner);
    // SOF, then at most 32 arbitration bits and the IDE/r0 that can still decide base against
    // extended.
    let span = la.min(lb).min(34);
    (1..span)
        .find_map(|i| {
            let bit_a = (a >> (la - 1 - i)) & 1;
            let bit_b = (b >> (lb - 1 - i)) & 1;
            match (bit_a, bit_b) {
                (1, 0) => Some(Some((i - 1) as u16)),
                (0, 1) => Some(None),
                _ => None,
            }
        })
        .flatten()
}

/// The position on the wire (stuff bits counted, SOF = 0) of the bit at unstuffed position
/// `index` (SOF = 0) of `frame`'s head (SOF to the end of the data field).
pub fn stuffed_position(frame: &Frame, index: u32) -> u32 {
    let (head, len) = unstuffed_head(frame);
    let mut position = 0;
    let mut run = 0;
    let mut last = 2u128;
    for i in 0..=index.min(len.saturating_sub(1)) {
        if run == 5 {
            // A stuff bit of the other level goes out first and starts a run of one.
            position += 1;
            last ^= 1;
            run = 1;
        }
        let bit = (head >> (len - 1 - i)) & 1;
        if bit == last {
            run += 1;
        } else {
            last = bit;
            run = 1;
        }
        if i < index {
            position += 1;
        }
    }
    position
}

/// CRC-15 of a right-aligned bit string. With init 0 leading zero bits leave the register
/// untouched, so left-padding to whole bytes lets the table-driven `crc` crate do the work.
fn crc15(bits: u128, len: u32) -> u16 {
    let nbytes = len.div_ceil(8) as usize;
    let be = bits.to_be_bytes();
    CAN_CRC.checksum(&be[16 - nbytes..])
}

/// Encodes a frame: stuffed bitstream, CRC and stuff-bit count.
pub fn encode(frame: &Frame) -> Encoded {
    let (head, head_len) = unstuffed_head(frame);
    let crc = crc15(head, head_len);
    let all = (head << 15) | u128::from(crc);
    let len = head_len + 15;
    let mut stuffed = BitStream::default();
    let mut stuff_bits = 0;
    let mut last = false;
    let mut run = 0u32;
    for i in (0..len).rev() {
        let bit = (all >> i) & 1 == 1;
        stuffed.push(bit);
        if bit == last && run > 0 {
            run += 1;
        } else {
            last = bit;
            run = 1;
        }
        if run == 5 {
            // The stuff bit is the complement and starts the next run.
            stuffed.push(!bit);
            stuff_bits += 1;
            last = !bit;
            run = 1;
        }
    }
    Encoded {
        stuffed,
        crc,
        stuff_bits,
    }
}

/// Exact bus time of a frame in bits, intermission included (can-utils' "exact" mode).
pub fn frame_bits(frame: &Frame) -> u32 {
    stuffed_len(frame) + TAIL_BITS
}

/// Length of the stuffed bitstream (SOF through the last CRC bit), as [`encode`] gives it,
/// stuffed a byte at a time through [`STUFF_TABLE`] instead of a bit at a time: what the bus
/// needs for every frame that goes through without an error.
pub fn stuffed_len(frame: &Frame) -> u32 {
    let (head, head_len) = unstuffed_head(frame);
    let crc = crc15(head, head_len);
    let all = (head << 15) | u128::from(crc);
    let len = head_len + 15;
    let mut state = 0usize;
    let mut stuff_bits = 0u32;
    // The first len % 8 bits one at a time, then whole bytes.
    let lead = len % 8;
    for i in (len - lead..len).rev() {
        let (next, stuffed) = stuff_bit(state, (all >> i) & 1 == 1);
        state = next;
        stuff_bits += stuffed;
    }
    for k in (0..(len - lead) / 8).rev() {
        let entry = STUFF_TABLE[state][((all >> (8 * k)) & 0xFF) as usize];
        state = usize::from(entry & 0xFF);
        stuff_bits += u32::from(entry >> 8);
    }
    len + stuff_bits
}

/// Stuffing state: the last bit of the stuffed stream (recessive or not) and the length of its
/// run, 0..=4 (0 only before the first bit; a run reaching 5 is cut by a stuff bit, which starts
/// a run of 1 of its own value), as `last * 5 + run`.
const STUFF_STATES: usize = 10;

/// One unstuffed bit through the stuffer: the next state and whether a stuff bit followed it.
const fn stuff_bit(state: usize, bit: bool) -> (usize, u32) {
    let last = state >= 5;
    let run = state % 5;
    let (last, run) = if run > 0 && bit == last {
        (last, run + 1)
    } else {
        (bit, 1)
    };
    if run == 5 {
        (if last { 1 } else { 6 }, 1)
    } else {
        (if last { 5 + run } else { run }, 0)
    }
}

/// For each state and byte (most significant bit first): the next state in the low byte and the
/// stuff bits inserted in the high byte.
static STUFF_TABLE: [[u16; 256]; STUFF_STATES] = {
    let mut table = [[0u16; 256]; STUFF_STATES];
    let mut state = 0;
    while state < STUFF_STATES {
        let mut byte = 0;
        while byte < 256 {
            let mut s = state;
            let mut stuffed = 0;
            let mut i = 8;
            while i > 0 {
                i -= 1;
                let (next, n) = stuff_bit(s, (byte >> i) & 1 == 1);
                s = next;
                stuffed += n;
            }
            table[state][byte] = (s as u16) | ((stuffed as u16) << 8);
            byte += 1;
        }
        state += 1;
    }
    table
};

/// Data bytes that count for the can-utils estimates: none for a remote frame.
fn data_len(frame: &Frame) -> u32 {
    frame.data().len() as u32
}

/// can-utils' worst case: 55 + 10n (base) or 80 + 10n (extended).
pub fn worst_case_bits(frame: &Frame) -> u32 {
    let n = data_len(frame);
    if frame.is_extended() {
        80 + 10 * n
    } else {
        55 + 10 * n
    }
}

/// can-utils' length without stuffing: 47 + 8n (base) or 67 + 8n (extended).
pub fn no_stuffing_bits(frame: &Frame) -> u32 {
    let n = data_len(frame);
    if frame.is_extended() {
        67 + 8 * n
    } else {
        47 + 8 * n
    }
}

/// A nominal bit rate in bit/s.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub struct BitRate(u32);

impl BitRate {
    /// 125 kbit/s.
    pub const K125: BitRate = BitRate(125_000);
    /// 250 kbit/s, the harvester's rate.
    pub const K250: BitRate = BitRate(250_000);
    /// 500 kbit/s.
    pub const K500: BitRate = BitRate(500_000);
    /// 1 Mbit/s.
    pub const M1: BitRate = BitRate(1_000_000);

    /// A bit rate; `None` for 0 or above 1 Mbit/s (classic CAN's limit).
    pub fn new(bits_per_second: u32) -> Option<BitRate> {
        (1..=1_000_000)
            .contains(&bits_per_second)
            .then_some(BitRate(bits_per_second))
    }

    /// Bits per second.
    pub fn bits_per_second(self) -> u32 {
        self.0
    }

    /// The slowest rate a harvester config takes, bit/s: 10 kbit/s, the lowest of the standard
    /// CAN bit rates (CiA 301's table: 10, 20, 50, 125, 250, 500, 800 and 1000 kbit/s).
    pub const SLOWEST: u32 = 10_000;

    /// The rule [`BitRate::for_bus`] applies, in words, for error messages.
    pub const RULE: &str = "a bit rate must be 10000 to 1000000 bit/s with a bit time the bus clock holds exactly: the rate must divide 3456000000000 (2^16 * 3^3 * 5^9), as 30000, 125000, 250000, 500000, 800000 and 1000000 do and 7000 or 33300 do not";

    /// A rate the emulated bus runs at: [`BitRate::SLOWEST`] to 1 Mbit/s, with a bit time of a
    /// whole number of bus-clock ticks ([`BitRate::RULE`]).
    pub fn for_bus(bits_per_second: u32) -> Option<BitRate> {
        BitRate::new(bits_per_second).filter(|r| r.0 >= BitRate::SLOWEST && r.bit_time().is_some())
    }

    /// The bit time, when it is a whole number of bus-clock ticks ([`crate::time`]), which the
    /// bus needs to stay exact: for every rate of the form 2^a · 3^b · 5^c with a ≤ 16, b ≤ 3,
    /// c ≤ 9 (all the standard CAN rates, and 30 kbit/s).
    pub fn bit_time(self) -> Option<BusDuration> {
        BusDuration::period_of(u64::from(self.0))
    }

    /// How long `bits` last, in microseconds, unrounded.
    pub fn duration_us(self, bits: u32) -> f64 {
        f64::from(bits) * 1e6 / f64::from(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candump::parse_frame;
    use crate::frame::{extended_id, standard_id};
    use proptest::prelude::*;

    /// (frame, CRC, stuff bits, total, worst case, no stuffing): the test vectors of docs/CAN.md, section 2.
    fn vectors() -> Vec<(Frame, u16, u32, u32, u32, u32)> {
        let f = |t: &str| parse_frame(t).unwrap();
        vec![
            (f("123#DEADBEEF"), 0x4E6B, 2, 81, 95, 79),
            (f("000#"), 0x0000, 6, 53, 55, 47),
            (f("7FF#R"), 0x54EA, 3, 50, 55, 47),
            (f("123#0000000000000000"), 0x044E, 14, 125, 135, 111),
            (f("0300A0F5#0102030405060708"), 0x6311, 11, 142, 160, 131),
            (f("1FFFFFFF#0000000000000000"), 0x7DA3, 20, 151, 160, 131),
            (f("00000000#"), 0x4610, 7, 74, 80, 67),
        ]
    }

    #[test]
    fn the_test_vectors_of_can_md() {
        for (frame, crc, stuff, total, worst, plain) in vectors() {
            let e = encode(&frame);
            let got = (
                e.crc,
                e.stuff_bits,
                e.total_bits(),
                worst_case_bits(&frame),
                no_stuffing_bits(&frame),
            );
            assert_eq!(got, (crc, stuff, total, worst, plain), "{frame:?}");
        }
    }

    #[test]
    fn the_worked_bitstream() {
        let e = encode(&parse_frame("123#DEADBEEF").unwrap());
        assert_eq!(
            e.stuffed.to_string(),
            "00010010001100001001101111010101101101111100111011111000111001101011"
        );
    }

    #[test]
    fn crc_check_value() {
        // "123456789" as a bit string: the crc crate's check value for CRC-15/CAN.
        let bytes = b"123456789";
        let v = bytes.iter().fold(0u128, |acc, &b| (acc << 8) | u128::from(b));
        assert_eq!(crc15(v, 72), 0x059E);
    }

    #[test]
    fn remote_frame_ignores_dlc_for_estimates() {
        let r = Frame::new_remote(standard_id(0x7FF).unwrap(), 8).unwrap();
        assert_eq!((worst_case_bits(&r), no_stuffing_bits(&r)), (55, 47));
        // ...but the DLC is on the wire, so the exact length sees it.
        let r0 = Frame::new_remote(standard_id(0x7FF).unwrap(), 0).unwrap();
        assert_ne!(encode(&r).crc, encode(&r0).crc);
    }

    #[test]
    fn durations() {
        assert_eq!(BitRate::K250.bit_time(), Some(BusDuration::from_nanos(4000)));
        assert_eq!(BitRate::K125.bit_time(), Some(BusDuration::from_nanos(8000)));
        assert_eq!(BitRate::M1.bit_time(), Some(BusDuration::from_nanos(1000)));
        let k30 = BitRate::new(30_000).and_then(BitRate::bit_time);
        assert_eq!(k30.map(|b| b * 3), Some(BusDuration::from_micros(100)));
        assert_eq!(BitRate::new(7_000).and_then(BitRate::bit_time), None);
        assert_eq!(BitRate::new(33_300).and_then(BitRate::bit_time), None);
    }

    #[test]
    fn a_bus_takes_every_rate_with_an_exact_bit_time_from_10_kbits() {
        // 3.456e12 = 2^16 × 3^3 × 5^9: the rates that divide it are 2^a × 3^b × 5^c.
        let mut exact: Vec<u32> = (0..=16u32)
            .flat_map(|a| (0..=3u32).flat_map(move |b| (0..=9u32).map(move |c| (a, b, c))))
            .map(|(a, b, c)| 2u64.pow(a) * 3u64.pow(b) * 5u64.pow(c))
            .filter(|r| (10_000..=1_000_000).contains(r))
            .map(|r| r as u32)
            .collect();
        exact.sort_unstable();
        let taken: Vec<u32> = (0..=1_100_000u32)
            .filter(|&r| BitRate::for_bus(r).is_some())
            .collect();
        assert_eq!(taken, exact);
        for r in [
            10_000, 20_000, 30_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ] {
            assert!(BitRate::for_bus(r).is_some(), "{r}");
        }
        for r in [
            0, 1, 5_000, 7_000, 9_999, 33_300, 33_333, 70_000, 1_000_001, 2_000_000,
        ] {
            assert!(BitRate::for_bus(r).is_none(), "{r}");
        }
        assert!(BitRate::new(0).is_none() && BitRate::new(1_000_001).is_none());
    }

    // ---- Independent bit-by-bit reference, written from the field table of docs/CAN.md ----

    fn push_bits(out: &mut Vec<bool>, value: u32, width: u32) {
        for i in (0..width).rev() {
            out.push((value >> i) & 1 == 1);
        }
    }

    /// SOF..end of data, unstuffed.
    fn reference_head(f: &Frame) -> Vec<bool> {
        let mut b = vec![false];
        match f.id() {
            Id::Standard(id) => {
                push_bits(&mut b, u32::from(id.as_raw()), 11);
                b.push(f.is_remote());
                b.extend([false, false]);
            }
            Id::Extended(id) => {
                let raw = id.as_raw();
                push_bits(&mut b, raw >> 18, 11);
                b.extend([true, true]);
                push_bits(&mut b, raw & 0x3FFFF, 18);
                b.push(f.is_remote());
                b.extend([false, false]);
            }
        }
        push_bits(&mut b, u32::from(f.dlc()), 4);
        for &byte in f.data() {
            push_bits(&mut b, u32::from(byte), 8);
        }
        b
    }

    /// The shift-register CRC of the Bosch specification, one bit at a time.
    fn reference_crc(bits: &[bool]) -> u16 {
        let mut reg: u16 = 0;
        for &bit in bits {
            let next = bit ^ (reg >> 14 & 1 == 1);
            reg = (reg << 1) & 0x7FFF;
            if next {
                reg ^= 0x4599;
            }
        }
        reg
    }

    /// Stuffing stated the other way round: look back at the last five bits already sent.
    fn reference_stuff(bits: &[bool]) -> (Vec<bool>, u32) {
        let mut out: Vec<bool> = Vec::new();
        let mut stuffed = 0;
        for &bit in bits {
            out.push(bit);
            let n = out.len();
            // A stuff bit already sent counts in the run, so looking back at what went on the
            // wire is the whole rule.
            if n >= 5 && out[n - 5..].iter().all(|&x| x == bit) {
                out.push(!bit);
                stuffed += 1;
            }
        }
        (out, stuffed)
    }

    fn arb_frame() -> impl Strategy<Value = Frame> {
        (
            any::<bool>(),
            any::<u32>(),
            any::<bool>(),
            0usize..=8,
            any::<[u8; 8]>(),
        )
            .prop_map(|(ext, raw, remote, len, data)| {
                let id: Id = if ext {
                    Id::Extended(extended_id(raw & 0x1FFF_FFFF).unwrap())
                } else {
                    Id::Standard(standard_id((raw & 0x7FF) as u16).unwrap())
                };
                if remote {
                    Frame::new_remote(id, len).unwrap()
                } else {
                    Frame::new_data(id, &data[..len]).unwrap()
                }
            })
    }

    /// Frames made of long runs of equal bits, where stuffing does the most.
    fn arb_runny_frame() -> impl Strategy<Value = Frame> {
        let byte = prop::sample::select(vec![
            0x00u8, 0xFF, 0x0F, 0xF0, 0x1F, 0xF8, 0x07, 0xE0, 0x3E, 0x83, 0x7C,
        ]);
        (
            any::<bool>(),
            prop::array::uniform4(byte.clone()),
            prop::array::uniform8(byte),
            0usize..=8,
        )
            .prop_map(|(ext, id, data, len)| {
                let raw = u32::from_be_bytes(id);
                let id: Id = if ext {
                    Id::Extended(extended_id(raw & 0x1FFF_FFFF).unwrap())
                } else {
                    Id::Standard(standard_id((raw & 0x7FF) as u16).unwrap())
                };
                Frame::new_data(id, &data[..len]).unwrap()
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn run_counting_matches_reference_on_long_runs(frame in arb_runny_frame()) {
            let mut bits = reference_head(&frame);
            let crc = reference_crc(&bits);
            push_bits(&mut bits, u32::from(crc), 15);
            let (stuffed, _) = reference_stuff(&bits);
            prop_assert_eq!(stuffed_len(&frame) as usize, stuffed.len());
        }

        #[test]
        fn encoder_matches_reference(frame in arb_frame()) {
            let mut bits = reference_head(&frame);
            let crc = reference_crc(&bits);
            push_bits(&mut bits, u32::from(crc), 15);
            let (stuffed, count) = reference_stuff(&bits);
            let e = encode(&frame);
            prop_assert_eq!(e.crc, crc);
            prop_assert_eq!(e.stuff_bits, count);
            let text: String = stuffed.iter().map(|&b| if b { '1' } else { '0' }).collect();
            prop_assert_eq!(e.stuffed.to_string(), text);
            prop_assert_eq!(e.total_bits() as usize, stuffed.len() + 13);
            prop_assert_eq!(frame_bits(&frame) as usize, stuffed.len() + 13);
            prop_assert!(no_stuffing_bits(&frame) <= e.total_bits());
            prop_assert!(e.total_bits() <= worst_case_bits(&frame));
        }

        #[test]
        fn arbitration_key_is_bus_order(a in arb_frame(), b in arb_frame()) {
            // On the wire the first differing arbitration bit decides, dominant (0) winning.
            let arb = |f: &Frame| {
                let head = reference_head(f);
                let n = if f.is_extended() { 33 } else { 14 }; // through RTR / IDE
                head[..n].to_vec()
            };
            let (x, y) = (arb(&a), arb(&b));
            let n = x.len().min(y.len());
            let expected = x[..n].cmp(&y[..n]);
            prop_assert_eq!(a.arbitration().cmp(&b.arbitration()), expected);
        }
    }
}
