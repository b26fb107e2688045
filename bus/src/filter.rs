//! Acceptance filters: which received frames a controller keeps.
//!
//! A CAN controller sees every frame on the bus; its acceptance filter decides, from the
//! identifier (and, depending on the form, the RTR bit and the first data bytes), whether the frame
//! goes into its receive buffer. Every form here implements [`AcceptanceFilter`]:
//!
//! - [`Sja1000Filter`]: the SJA1000 in PeliCAN mode (ACR0–3 / AMR0–3, AMR bit 1 = don't care),
//!   single and dual filter, base and extended frames, as in the Philips SJA1000 data sheet
//!   (product specification, 2000 Jan 04, section 6.4.15) and QEMU's `hw/net/can/can_sja1000.c`.
//! - [`SocketCanFilter`] and [`SocketCanFilterSet`]: `struct can_filter` of a Linux raw CAN socket,
//!   with the semantics of the kernel's `net/can/af_can.c` (`can_rcv_list_find`,
//!   `can_rcv_filter`).
//! - [`AtmelFilter`]: a message object of the Atmel AT89C51CC01/CC03 and ATmega32M1
//!   (CANIDT1–4 / CANIDM1–4, left-aligned identifier, CANIDM bit 1 = compare).
//!
//! [`acr_bytes_for`] and [`canidt_bytes`] give the register images of an identifier; the seed's
//! worked example (`0x0300A0F5` -> CANIDT1..4 = `18 05 07 A8`) is a test below.
//!
//! Every function is total: no I/O, no panics.

use crate::Frame;
use embedded_can::Id;
use serde::{Deserialize, Serialize};

/// The decision a controller's acceptance filter makes for each received frame.
pub trait AcceptanceFilter {
    /// True when the controller would store `frame` in its receive buffer.
    fn accepts(&self, frame: &Frame) -> bool;
}

/// The identifier as a number: 11 or 29 significant bits.
fn raw_id(id: Id) -> u32 {
    match id {
        Id::Standard(id) => u32::from(id.as_raw()),
        Id::Extended(id) => id.as_raw(),
    }
}

/// True when `image` and `code` agree on every bit set in `compare`.
fn bits_match(image: u32, code: u32, compare: u32) -> bool {
    (image ^ code) & compare == 0
}

// ---------------------------------------------------------------------------------------------
// SJA1000
// ---------------------------------------------------------------------------------------------

/// Which bits of ACR0..3 (read as one big-endian `u32`, ACR0 in bits 31..24) each SJA1000 filter
/// compares, per the data sheet's figures 9–12. Declared once; `accepts` and the register images
/// both use them.
mod sja {
    /// Single filter, extended frame: ID28..0 in 31..3, RTR in 2; ACR3 bits 1:0 are unused.
    pub const SINGLE_EXT: u32 = 0xFFFF_FFFC;
    /// Single filter, base frame: ID10..0 in 31..21, RTR in 20; ACR1 bits 3:0 are unused.
    pub const SINGLE_BASE_ID: u32 = 0xFFF0_0000;
    /// Single filter, base frame: data byte 1 against ACR2.
    pub const SINGLE_BASE_DATA1: u32 = 0x0000_FF00;
    /// Single filter, base frame: data byte 2 against ACR3.
    pub const SINGLE_BASE_DATA2: u32 = 0x0000_00FF;
    /// Dual filter, extended frame, filter 1: ID28..13 against ACR0:ACR1.
    pub const DUAL_EXT_1: u32 = 0xFFFF_0000;
    /// Dual filter, extended frame, filter 2: ID28..13 against ACR2:ACR3.
    pub const DUAL_EXT_2: u32 = 0x0000_FFFF;
    /// Dual filter, base frame, filter 1: ID10..0 and RTR against ACR0 and ACR1 bits 7:4.
    pub const DUAL_BASE_1_ID: u32 = 0xFFF0_0000;
    /// Dual filter, base frame, filter 1: data byte 1, high nibble against ACR1 bits 3:0, low
    /// nibble against ACR3 bits 3:0.
    pub const DUAL_BASE_1_DATA: u32 = 0x000F_000F;
    /// Dual filter, base frame, filter 2: ID10..0 and RTR against ACR2 and ACR3 bits 7:4.
    pub const DUAL_BASE_2: u32 = 0x0000_FFF0;
    /// The AFM bit of the MOD register: set = single filter.
    pub const MOD_AFM: u8 = 0x08;
}

/// The SJA1000 acceptance filter mode, bit AFM of the MOD register.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub enum Sja1000Mode {
    /// AFM = 1: one long filter over all four ACR/AMR pairs.
    Single,
    /// AFM = 0: two short filters; a frame is accepted if either accepts it.
    Dual,
}

impl Sja1000Mode {
    /// The mode selected by a value of the MOD register (AFM = 0x08).
    pub fn from_mod_register(value: u8) -> Sja1000Mode {
        if value & sja::MOD_AFM != 0 {
            Sja1000Mode::Single
        } else {
            Sja1000Mode::Dual
        }
    }
}

/// The SJA1000 (PeliCAN mode) acceptance filter: the AFM mode bit, ACR0–3 and AMR0–3.
///
/// A mask bit of 1 means "don't care"; a 0 means the message bit must equal the code bit. What is
/// compared depends on the mode and on the received frame's format (data sheet 6.4.15):
///
/// | mode | frame | compared |
/// |---|---|---|
/// | single | extended | ACR0..3 = ID28..21, ID20..13, ID12..5, ID4..0 in 7:3 and RTR in 2 (ACR3 1:0 unused) |
/// | single | base | ACR0 = ID10..3, ACR1 7:5 = ID2..0, ACR1 4 = RTR (ACR1 3:0 unused), ACR2 = data byte 1, ACR3 = data byte 2 |
/// | dual | extended | filter 1: ACR0:ACR1 = ID28..13; filter 2: ACR2:ACR3 = ID28..13 (RTR not compared) |
/// | dual | base | filter 1: ACR0 = ID10..3, ACR1 7:5 = ID2..0, ACR1 4 = RTR, ACR1 3:0 = data byte 1 7:4, ACR3 3:0 = data byte 1 3:0; filter 2: ACR2 = ID10..3, ACR3 7:5 = ID2..0, ACR3 4 = RTR |
///
/// Data-byte bits only take part when the frame has that byte. Data sheet 6.4.15.1 (single,
/// base frame): messages are also accepted when no data byte exists because RTR is set, or when
/// there is no or only one data byte because of the DLC. Data sheet 6.4.15.2 (dual, base frame): "In
/// case of a set RTR bit or a data length code of logic 0 no data byte is existing. Nevertheless a
/// message may pass filter 1, if the first part up to the RTR bit signals acceptance."
///
/// Differences from QEMU's `can_sja_accept_filter`, where this follows the data sheet instead:
/// - QEMU before commit 25145a7d77 (issue #2028, "fix bug for single acceptance filter and
///   standard frame") built the single-filter base-frame mask with `amr[1] << 5` instead of
///   `>> 5`; the fixed version agrees with this model.
/// - QEMU's dual-filter base-frame path compares data byte 1 of filter 1 even for a remote frame
///   or DLC 0 (it reads a zeroed byte); this model skips the data nibbles then, as the data sheet
///   says.
///
/// The Linux driver (`drivers/net/can/sja1000/sja1000.c`) leaves the filter fully open (ACR 0,
/// AMR 0xFF, dual mode), so it gives no further evidence either way.
///
/// The filter has no IDE bit: a frame of either format is compared with the layout of its own
/// format, so a filter written for an extended identifier can also pass some base frames (see
/// [`Sja1000Filter::single_exact`]).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sja1000Filter {
    /// Single or dual filter (MOD.AFM).
    pub mode: Sja1000Mode,
    /// Acceptance code registers ACR0..3 (CAN addresses 16–19 in reset mode).
    pub acr: [u8; 4],
    /// Acceptance mask registers AMR0..3 (CAN addresses 20–23 in reset mode); 1 = don't care.
    pub amr: [u8; 4],
}

impl Sja1000Filter {
    /// A filter that accepts every frame: single mode, ACR all 0, AMR all 0xFF.
    pub fn accept_all() -> Sja1000Filter {
        Sja1000Filter {
            mode: Sja1000Mode::Single,
            acr: [0; 4],
            amr: [0xFF; 4],
        }
    }

    /// A single filter that accepts data frames with exactly this identifier.
    ///
    /// RTR must match (must be 0): the harvester carries information only in data frames, and the
    /// seed uses remote frames for a node's own debugging, so a receiver set up for one message
    /// should not take remote frames for it. The unused bits (ACR3 1:0 for an extended filter, ACR1
    /// 3:0 for a base filter) are don't care, as the data sheet recommends, and for a base
    /// identifier the data bytes are don't care.
    ///
    /// The SJA1000 cannot tell the formats apart in its filter: an extended filter also passes a
    /// base frame whose ID10..0 equal ID28..18 of the extended identifier, whose RTR bit equals
    /// ID17 and whose data bytes, where present, equal ACR2 and ACR3 bits 7:2. That is the chip's
    /// behaviour and it is kept here.
    pub fn single_exact(frame_id: Id) -> Sja1000Filter {
        let amr = match frame_id {
            Id::Extended(_) => (!sja::SINGLE_EXT).to_be_bytes(),
            Id::Standard(_) => (!sja::SINGLE_BASE_ID).to_be_bytes(),
        };
        Sja1000Filter {
            mode: Sja1000Mode::Single,
            acr: acr_bytes_for(frame_id, false),
            amr,
        }
    }

    /// Whether filter 1, filter 2 (dual mode) or the one filter (single mode, reported as
    /// filter 1) accepts `frame`: `[filter 1, filter 2]`.
    fn hits(&self, frame: &Frame) -> [bool; 2] {
        let code = u32::from_be_bytes(self.acr);
        let compare = !u32::from_be_bytes(self.amr);
        let id = frame.raw_id();
        let rtr = u32::from(frame.is_remote());
        // `data()` is empty for a remote frame, so "has byte n" covers both the RTR and the DLC
        // rule of the data sheet.
        let data = frame.data();
        match (self.mode, frame.is_extended()) {
            (Sja1000Mode::Single, true) => {
                let image = (id << 3) | (rtr << 2);
                [bits_match(image, code, compare & sja::SINGLE_EXT), false]
            }
            (Sja1000Mode::Single, false) => {
                let mut image = (id << 21) | (rtr << 20);
                let mut used = sja::SINGLE_BASE_ID;
                if let Some(&b) = data.first() {
                    image |= u32::from(b) << 8;
                    used |= sja::SINGLE_BASE_DATA1;
                }
                if let Some(&b) = data.get(1) {
                    image |= u32::from(b);
                    used |= sja::SINGLE_BASE_DATA2;
                }
                [bits_match(image, code, compare & used), false]
            }
            (Sja1000Mode::Dual, true) => {
                let high = id >> 13;
                let image = (high << 16) | high;
                [
                    bits_match(image, code, compare & sja::DUAL_EXT_1),
                    bits_match(image, code, compare & sja::DUAL_EXT_2),
                ]
            }
            (Sja1000Mode::Dual, false) => {
                // ID10..0 and RTR fill bits 15..4 of each half; bits 3:0 of each half are where
                // filter 1 keeps its data nibbles.
                let head = (id << 5) | (rtr << 4);
                let mut image = (head << 16) | head;
                let mut used_1 = sja::DUAL_BASE_1_ID;
                if let Some(&b) = data.first() {
                    image |= (u32::from(b >> 4) << 16) | u32::from(b & 0x0F);
                    used_1 |= sja::DUAL_BASE_1_DATA;
                }
                [
                    bits_match(image, code, compare & used_1),
                    bits_match(image, code, compare & sja::DUAL_BASE_2),
                ]
            }
        }
    }
}

impl AcceptanceFilter for Sja1000Filter {
    fn accepts(&self, frame: &Frame) -> bool {
        let [one, two] = self.hits(frame);
        one || two
    }
}

/// The SJA1000 single-filter ACR0..3 layout of an identifier and RTR bit: the ACR bytes that,
/// with AMR 0 on every used bit, accept exactly this identifier.
///
/// Extended: ID28..21, ID20..13, ID12..5, ID4..0 in bits 7:3 with RTR in bit 2 (the same bytes as
/// the RX/TX frame window at CAN addresses 17–20). Base: ID10..3, then ID2..0 in bits 7:5 with RTR
/// in bit 4, then two bytes for data bytes 1 and 2, given here as 0. Unused bits are 0.
pub fn acr_bytes_for(id: Id, remote: bool) -> [u8; 4] {
    let rtr = u32::from(remote);
    let image = match id {
        Id::Extended(_) => (raw_id(id) << 3) | (rtr << 2),
        Id::Standard(_) => (raw_id(id) << 21) | (rtr << 20),
    };
    image.to_be_bytes()
}

// ---------------------------------------------------------------------------------------------
// SocketCAN
// ---------------------------------------------------------------------------------------------

/// `can_id` flag: the frame has a 29-bit identifier (`include/uapi/linux/can.h`).
pub const CAN_EFF_FLAG: u32 = 0x8000_0000;
/// `can_id` flag: remote transmission request.
pub const CAN_RTR_FLAG: u32 = 0x4000_0000;
/// `can_id` flag: error message frame.
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;
/// The identifier bits of a base frame.
pub const CAN_SFF_MASK: u32 = 0x0000_07FF;
/// The identifier bits of an extended frame.
pub const CAN_EFF_MASK: u32 = 0x1FFF_FFFF;
/// The class bits of an error frame's `can_id` (everything but the three flags).
pub const CAN_ERR_MASK: u32 = 0x1FFF_FFFF;
/// In a filter's `can_id`: invert the match. Same bit as [`CAN_ERR_FLAG`]; its meaning depends
/// on where it appears.
pub const CAN_INV_FILTER: u32 = 0x2000_0000;

/// A frame's identifier in `struct can_frame` form: the raw identifier, with [`CAN_EFF_FLAG`] for
/// an extended frame and [`CAN_RTR_FLAG`] for a remote frame.
pub fn kernel_can_id(frame: &Frame) -> u32 {
    let mut can_id = frame.raw_id();
    if frame.is_extended() {
        can_id |= CAN_EFF_FLAG;
    }
    if frame.is_remote() {
        can_id |= CAN_RTR_FLAG;
    }
    can_id
}

/// One `struct can_filter` of a raw CAN socket (`CAN_RAW_FILTER`).
///
/// Matches when `rx_can_id & can_mask == can_id & can_mask`, with the kernel's refinements
/// (`net/can/af_can.c`, `can_rcv_list_find` at registration and `can_rcv_filter` at reception):
/// - [`CAN_INV_FILTER`] in `can_id` inverts the result.
/// - [`CAN_ERR_FLAG`] in `can_mask` makes it an error-frame filter: it matches only error frames
///   whose class bits meet `can_mask & CAN_ERR_MASK`, whatever [`CAN_INV_FILTER`] says, and never a
///   data or remote frame.
/// - An "SFF only" filter ([`CAN_EFF_FLAG`] in the mask but not in `can_id`) has its mask cut to
///   [`CAN_SFF_MASK`] plus the EFF and RTR flags, so identifier bits 11..28 of `can_id` are ignored.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SocketCanFilter {
    /// The identifier to match, with flags; [`CAN_INV_FILTER`] inverts the filter.
    pub can_id: u32,
    /// Which bits of the received `can_id` are compared.
    pub can_mask: u32,
}

impl SocketCanFilter {
    /// A filter from its two fields.
    pub fn new(can_id: u32, can_mask: u32) -> SocketCanFilter {
        SocketCanFilter { can_id, can_mask }
    }

    /// `{ 0, 0 }`: matches every data and remote frame, the raw socket's default filter.
    pub fn accept_all() -> SocketCanFilter {
        SocketCanFilter::new(0, 0)
    }

    /// Matches data frames with exactly this identifier and format (the kernel's single-id form:
    /// mask = identifier bits | EFF | RTR, RTR clear in `can_id`).
    pub fn exact(id: Id) -> SocketCanFilter {
        let (flag, bits) = match id {
            Id::Extended(_) => (CAN_EFF_FLAG, CAN_EFF_MASK),
            Id::Standard(_) => (0, CAN_SFF_MASK),
        };
        SocketCanFilter::new(raw_id(id) | flag, bits | CAN_EFF_FLAG | CAN_RTR_FLAG)
    }

    /// The same filter with [`CAN_INV_FILTER`] toggled.
    pub fn inverted(self) -> SocketCanFilter {
        SocketCanFilter::new(self.can_id ^ CAN_INV_FILTER, self.can_mask)
    }

    /// Whether a received `can_id` (in `struct can_frame` form, possibly an error frame) passes.
    pub fn matches_can_id(&self, rx_can_id: u32) -> bool {
        let mut mask = self.can_mask;
        if rx_can_id & CAN_ERR_FLAG != 0 {
            // Error frames are checked only against the error filter list, where the kernel
            // tests `can_id & mask` and ignores the inversion flag.
            return mask & CAN_ERR_FLAG != 0 && rx_can_id & mask & CAN_ERR_MASK != 0;
        }
        if mask & CAN_ERR_FLAG != 0 {
            // Registered on the error list: no data or remote frame ever reaches it.
            return false;
        }
        if mask & CAN_EFF_FLAG != 0 && self.can_id & CAN_EFF_FLAG == 0 {
            mask &= CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
        }
        // The mask has no CAN_ERR_FLAG here, so the inversion bit of `can_id` drops out.
        let hit = rx_can_id & mask == self.can_id & mask;
        hit != (self.can_id & CAN_INV_FILTER != 0)
    }
}

impl AcceptanceFilter for SocketCanFilter {
    fn accepts(&self, frame: &Frame) -> bool {
        self.matches_can_id(kernel_can_id(frame))
    }
}

/// The filter list of one raw CAN socket: a frame is received if any filter matches, and
/// delivered once even when several do (`raw.c` drops duplicates of one frame).
///
/// An empty set receives nothing, as `setsockopt(CAN_RAW_FILTER)` with zero filters does; a fresh
/// socket instead starts with `[SocketCanFilter::accept_all()]`. `CAN_RAW_JOIN_FILTERS` (all
/// filters must match) is not modelled.
#[derive(Clone, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[serde(transparent)]
pub struct SocketCanFilterSet(pub Vec<SocketCanFilter>);

impl AcceptanceFilter for SocketCanFilterSet {
    fn accepts(&self, frame: &Frame) -> bool {
        let can_id = kernel_can_id(frame);
        self.0.iter().any(|f| f.matches_can_id(can_id))
    }
}

// ---------------------------------------------------------------------------------------------
// Atmel AT89C51CC01/CC03, ATmega32M1
// ---------------------------------------------------------------------------------------------

/// Bits of CANIDT1..4 / CANIDM1..4 read as one big-endian `u32` (CANIDT1 in bits 31..24).
mod atmel {
    /// Extended (V2.0 part B): IDT28..0 in bits 31..3.
    pub const ID_EXT: u32 = 0xFFFF_FFF8;
    /// Base (V2.0 part A): IDT10..0 in bits 31..21 (CANIDT1, CANIDT2 7:5).
    pub const ID_BASE: u32 = 0xFFE0_0000;
    /// RTRTAG / RTRMSK: CANIDT4 / CANIDM4 bit 2.
    pub const RTR: u32 = 0x0000_0004;
}

/// One message object's acceptance filter on the Atmel CAN controllers (AT89C51CC01/CC03,
/// ATmega32M1): CANIDT1..4, CANIDM1..4 and the IDE bit of CANCDMOB.
///
/// The identifier is left-aligned: CANIDT1..4 = ID28..21, ID20..13, ID12..5, ID4..0 in 7:3, then
/// RTRTAG (bit 2), RB1TAG (bit 1), RB0TAG (bit 0); a base identifier sits in CANIDT1 (ID10..3) and
/// CANIDT2 7:5 (ID2..0). CANIDM uses the opposite sense to the SJA1000: 1 = compare this bit,
/// 0 = don't care; RTRMSK is CANIDM4 bit 2.
///
/// Modelling decisions:
/// - The IDE comparison uses the `ide` and `ide_mask` fields only; bit 0 of `idm[3]` (where the
///   chip keeps IDEMSK) is not read. [`AtmelFilter::exact`] sets both to the same value.
/// - Only the identifier bits of the received frame's own format are compared: for a base frame
///   CANIDT2 4:0 and CANIDT3..4 7:3 take no part.
/// - RB1TAG and RB0TAG have no mask bit and are not compared. A received frame's reserved bits are
///   dominant (0), so a filter that keeps them 0, as [`canidt_bytes`] does, behaves the same if a
///   chip does compare them.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AtmelFilter {
    /// CANIDT1..4: identifier tag, RTRTAG, RB1TAG, RB0TAG.
    pub idt: [u8; 4],
    /// CANIDM1..4: identifier mask, RTRMSK (bit 2 of CANIDM4); 1 = compare.
    pub idm: [u8; 4],
    /// IDE of CANCDMOB: true = the MOb is set up for extended frames.
    pub ide: bool,
    /// IDEMSK: true = the frame's format must equal `ide`; false = either format.
    pub ide_mask: bool,
}

impl AtmelFilter {
    /// RTRMSK in CANIDM4.
    pub const RTRMSK: u8 = 0x04;
    /// IDEMSK in CANIDM4.
    pub const IDEMSK: u8 = 0x01;

    /// A filter that accepts data frames with exactly this identifier and format: every identifier
    /// bit, RTRMSK and IDEMSK set, RTRTAG 0. This is how the seed sets up CanModuleA for
    /// `0x0300A0F5` (CANIDT1..4 = `18 05 07 A8`).
    pub fn exact(id: Id) -> AtmelFilter {
        let id_bits = match id {
            Id::Extended(_) => atmel::ID_EXT,
            Id::Standard(_) => atmel::ID_BASE,
        };
        let mut idm = (id_bits | atmel::RTR).to_be_bytes();
        idm[3] |= AtmelFilter::IDEMSK;
        AtmelFilter {
            idt: canidt_bytes(id, false),
            idm,
            ide: matches!(id, Id::Extended(_)),
            ide_mask: true,
        }
    }
}

impl AcceptanceFilter for AtmelFilter {
    fn accepts(&self, frame: &Frame) -> bool {
        if self.ide_mask && frame.is_extended() != self.ide {
            return false;
        }
        let image = u32::from_be_bytes(canidt_bytes(frame.id(), frame.is_remote()));
        let id_bits = if frame.is_extended() {
            atmel::ID_EXT
        } else {
            atmel::ID_BASE
        };
        let compare = u32::from_be_bytes(self.idm) & (id_bits | atmel::RTR);
        bits_match(image, u32::from_be_bytes(self.idt), compare)
    }
}

/// CANIDT1..4 of an identifier and RTR bit, left-aligned: for an extended identifier the 29 bits
/// shifted left by 3 with RTRTAG in bit 2 (`0x0300A0F5` -> `18 05 07 A8`); for a base identifier
/// ID10..3, then ID2..0 in bits 7:5, and RTRTAG in CANIDT4 bit 2. RB1TAG and RB0TAG are 0.
pub fn canidt_bytes(id: Id, remote: bool) -> [u8; 4] {
    let rtr = if remote { atmel::RTR } else { 0 };
    let image = match id {
        Id::Extended(_) => raw_id(id) << 3,
        Id::Standard(_) => raw_id(id) << 21,
    };
    (image | rtr).to_be_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{extended_id, standard_id};
    use proptest::prelude::*;

    fn ext(raw: u32) -> Id {
        Id::Extended(extended_id(raw).unwrap())
    }
    fn base(raw: u16) -> Id {
        Id::Standard(standard_id(raw).unwrap())
    }
    fn data(id: Id, bytes: &[u8]) -> Frame {
        Frame::new_data(id, bytes).unwrap()
    }
    fn remote(id: Id) -> Frame {
        Frame::new_remote(id, 0).unwrap()
    }
    fn sja(mode: Sja1000Mode, acr: [u8; 4], amr: [u8; 4]) -> Sja1000Filter {
        Sja1000Filter { mode, acr, amr }
    }

    /// Every identifier the harvester can produce: priority 0..31 (bits 28..24), frame type 0..1
    /// (bits 23..16), and each of its 21 node addresses as destination (bits 15..8) and source
    /// (bits 7..0). The layout is written out here, apart from the protocol crate's codec.
    fn harvester_ids() -> Vec<u32> {
        const ADDRESSES: [u32; 21] = [
            0xF5, 0xD0, 0xD1, 0xD2, 0xD3, 0xD4, 0xD5, 0xA0, 0xB0, 0xB1, 0xB2, 0xB3, 0xB4, 0xB5, 0xB6, 0xB7,
            0xC0, 0xC1, 0xC2, 0xC3, 0xE0,
        ];
        let mut ids = Vec::new();
        for p in 0..32 {
            for t in 0..2 {
                for dst in ADDRESSES {
                    for src in ADDRESSES {
                        ids.push(p << 24 | t << 16 | dst << 8 | src);
                    }
                }
            }
        }
        ids
    }

    // --- the seed's worked example ---------------------------------------------------------

    #[test]
    fn seed_canidt_bytes_of_the_row_alignment_command() {
        assert_eq!(canidt_bytes(ext(0x0300A0F5), false), [0x18, 0x05, 0x07, 0xA8]);
        // "that is, the 29-bit ID shifted left by 3"
        assert_eq!(
            u32::from_be_bytes(canidt_bytes(ext(0x0300A0F5), false)),
            0x0300A0F5 << 3
        );
        assert_eq!(canidt_bytes(ext(0x0300A0F5), true), [0x18, 0x05, 0x07, 0xAC]);
        // The SJA1000's extended single-filter layout is the same left-aligned image.
        assert_eq!(acr_bytes_for(ext(0x0300A0F5), false), [0x18, 0x05, 0x07, 0xA8]);
    }

    #[test]
    fn seed_exact_filter_accepts_only_its_identifier() {
        let f = AtmelFilter::exact(ext(0x0300A0F5));
        assert_eq!(f.idt, [0x18, 0x05, 0x07, 0xA8]);
        assert_eq!(f.idm, [0xFF, 0xFF, 0xFF, 0xFD]);
        assert!(f.ide && f.ide_mask);

        let ids = harvester_ids();
        assert_eq!(ids.len(), 32 * 2 * 21 * 21);
        assert!(ids.contains(&0x0300A0F5) && ids.contains(&0x0300F5A0));
        let mut accepted = 0;
        for &raw in &ids {
            let frame = data(ext(raw), &[1, 2]);
            let yes = f.accepts(&frame);
            assert_eq!(yes, raw == 0x0300A0F5, "{raw:08X}");
            accepted += usize::from(yes);
            // Remote frames are refused: RTRMSK is set and RTRTAG is 0.
            assert!(!f.accepts(&remote(ext(raw))), "remote {raw:08X}");
        }
        assert_eq!(accepted, 1);
        assert!(!f.accepts(&data(ext(0x0300F5A0), &[])), "the reply A0 -> F5");
        // Base-frame lookalikes: every 11-bit identifier, data and remote, including 0x0C0
        // (= ID28..18 of 0x0300A0F5).
        assert_eq!(0x0300A0F5 >> 18, 0x0C0);
        for raw in 0..=0x7FF {
            assert!(!f.accepts(&data(base(raw), &[0x07, 0xA8])), "base {raw:03X}");
            assert!(!f.accepts(&remote(base(raw))), "base remote {raw:03X}");
        }
    }

    #[test]
    fn seed_sja1000_single_exact_over_the_harvester_identifiers() {
        let f = Sja1000Filter::single_exact(ext(0x0300A0F5));
        assert_eq!(f.acr, [0x18, 0x05, 0x07, 0xA8]);
        assert_eq!(f.amr, [0x00, 0x00, 0x00, 0x03]);
        for raw in harvester_ids() {
            assert_eq!(f.accepts(&data(ext(raw), &[9])), raw == 0x0300A0F5, "{raw:08X}");
            assert!(!f.accepts(&remote(ext(raw))), "remote {raw:08X}");
        }
    }

    // --- SJA1000 ---------------------------------------------------------------------------

    #[test]
    fn sja1000_single_extended() {
        let f = sja(Sja1000Mode::Single, [0x18, 0x05, 0x07, 0xA8], [0, 0, 0, 0]);
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])));
        assert!(!f.accepts(&data(ext(0x0300A0F4), &[])));
        assert!(!f.accepts(&remote(ext(0x0300A0F5))), "RTR compared");
        // ACR3 bits 1:0 are unused: a code with them set still matches.
        let f = sja(Sja1000Mode::Single, [0x18, 0x05, 0x07, 0xAB], [0, 0, 0, 0]);
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])));
        // Don't care on the source byte (ID7..0 = ACR2 bits 2:0, ACR3 bits 7:3) and on RTR.
        let f = sja(Sja1000Mode::Single, [0x18, 0x05, 0x07, 0xA8], [0, 0, 0x07, 0xFC]);
        for src in [0x00, 0xF5, 0xA0, 0xFF] {
            assert!(f.accepts(&data(ext(0x0300A000 | src), &[1])));
            assert!(f.accepts(&remote(ext(0x0300A000 | src))));
        }
        assert!(!f.accepts(&data(ext(0x0300B0F5), &[1])), "destination compared");
    }

    #[test]
    fn sja1000_seed_002_example_first_byte_only() {
        // MOD = 0x09 (single filter), ACR0 = own code, ACR1..3 = 0xFF, AMR0 = 0, AMR1..3 = 0xFF.
        let f = Sja1000Filter {
            mode: Sja1000Mode::from_mod_register(0x09),
            acr: [0x18, 0xFF, 0xFF, 0xFF],
            amr: [0x00, 0xFF, 0xFF, 0xFF],
        };
        assert_eq!(f.mode, Sja1000Mode::Single);
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])), "ID28..21 = 0x18");
        assert!(f.accepts(&data(ext(0x0300F5A0), &[1, 2, 3])));
        assert!(!f.accepts(&data(ext(0x0601F5D0), &[])));
        assert!(f.accepts(&data(base(0x0C5), &[])), "ID10..3 = 0x18");
        assert!(!f.accepts(&data(base(0x1C5), &[])));
        assert_eq!(Sja1000Mode::from_mod_register(0x00), Sja1000Mode::Dual);
    }

    #[test]
    fn sja1000_single_base_compares_data_bytes_only_when_present() {
        // ID 0x123 -> ACR0 = 0x24, ACR1 = 011 0 xxxx; data byte 1 = 0xDE, data byte 2 = 0xAD.
        let f = sja(Sja1000Mode::Single, [0x24, 0x60, 0xDE, 0xAD], [0, 0x0F, 0, 0]);
        assert_eq!(acr_bytes_for(base(0x123), false), [0x24, 0x60, 0, 0]);
        assert_eq!(acr_bytes_for(base(0x123), true), [0x24, 0x70, 0, 0]);
        let id = base(0x123);
        assert!(f.accepts(&data(id, &[0xDE, 0xAD, 0xBE, 0xEF])));
        assert!(!f.accepts(&data(id, &[0xDE, 0xAC])), "data byte 2 compared");
        assert!(!f.accepts(&data(id, &[0xDF, 0xAD])), "data byte 1 compared");
        assert!(f.accepts(&data(id, &[0xDE])), "no data byte 2: its bits unused");
        assert!(!f.accepts(&data(id, &[0xDF])));
        assert!(f.accepts(&data(id, &[])), "DLC 0: no data bits used");
        assert!(!f.accepts(&data(base(0x122), &[0xDE, 0xAD])));
        // A remote frame has no data bytes, but RTR itself is compared (ACR1 bit 4 = 0).
        assert!(!f.accepts(&remote(id)));
        let f_rtr = sja(Sja1000Mode::Single, [0x24, 0x70, 0xDE, 0xAD], [0, 0x0F, 0, 0]);
        assert!(f_rtr.accepts(&Frame::new_remote(id, 8).unwrap()));
        // ACR1 bits 3:0 are unused even when AMR1 asks to compare them.
        let f = sja(Sja1000Mode::Single, [0x24, 0x6F, 0, 0], [0, 0, 0xFF, 0xFF]);
        assert!(f.accepts(&data(id, &[1, 2])));
    }

    #[test]
    fn sja1000_single_base_mask_uses_amr1_high_bits() {
        // QEMU issue #2028: AMR1 was shifted left instead of right. With AMR1 = 0x0F (unused bits
        // don't care) ID2..0 must still be compared, and ID8..5 must not become don't care.
        let f = sja(Sja1000Mode::Single, [0x24, 0x60, 0, 0], [0x00, 0x0F, 0xFF, 0xFF]);
        assert!(f.accepts(&data(base(0x123), &[])));
        assert!(!f.accepts(&data(base(0x122), &[])));
        assert!(!f.accepts(&data(base(0x103), &[])));
        // AMR1 = 0xE0: ID2..0 don't care.
        let f = sja(Sja1000Mode::Single, [0x24, 0x00, 0, 0], [0x00, 0xEF, 0xFF, 0xFF]);
        for low in 0..8 {
            assert!(f.accepts(&data(base(0x120 | low), &[])));
        }
        assert!(!f.accepts(&data(base(0x128), &[])));
    }

    #[test]
    fn sja1000_single_exact_base_and_its_format_blindness() {
        let f = Sja1000Filter::single_exact(base(0x123));
        assert_eq!(f.acr, [0x24, 0x60, 0, 0]);
        assert_eq!(f.amr, [0x00, 0x0F, 0xFF, 0xFF]);
        assert!(f.accepts(&data(base(0x123), &[1, 2, 3])));
        assert!(!f.accepts(&remote(base(0x123))));
        assert!(!f.accepts(&data(base(0x124), &[])));

        // The chip has no IDE bit in its filter: a base frame 0x0C0 with no data passes the
        // extended filter for 0x0300A0F5 (ACR1 7:5 = 000 = its ID2..0, ACR1 bit 4 = 0 = RTR).
        let f = Sja1000Filter::single_exact(ext(0x0300A0F5));
        assert!(f.accepts(&data(base(0x0C0), &[])));
        assert!(f.accepts(&data(base(0x0C0), &[0x07, 0xA8, 0x55])));
        assert!(!f.accepts(&data(base(0x0C0), &[0x07, 0xAC])));
        // AMR3 bits 1:0 (unused in the extended layout) leave data byte 2 bits 1:0 open.
        assert!(f.accepts(&data(base(0x0C0), &[0x07, 0xAB])));
        assert!(!f.accepts(&data(base(0x0C1), &[])));
    }

    #[test]
    fn sja1000_accept_all() {
        let f = Sja1000Filter::accept_all();
        for frame in [
            data(ext(0x1FFF_FFFF), &[0xFF; 8]),
            data(base(0), &[]),
            remote(base(0x7FF)),
            remote(ext(0)),
        ] {
            assert!(f.accepts(&frame));
            let dual = Sja1000Filter {
                mode: Sja1000Mode::Dual,
                ..f
            };
            assert!(dual.accepts(&frame));
        }
    }

    #[test]
    fn sja1000_dual_extended_either_side() {
        // Filter 1: ID28..13 of 0x0300A0F5 = 0x1805; filter 2: of 0x0601F5D0 = 0x300F.
        assert_eq!(0x0300A0F5 >> 13, 0x1805);
        assert_eq!(0x0601F5D0 >> 13, 0x300F);
        let f = sja(Sja1000Mode::Dual, [0x18, 0x05, 0x30, 0x0F], [0, 0, 0, 0]);
        assert_eq!(f.hits(&data(ext(0x0300A0F5), &[])), [true, false]);
        assert_eq!(f.hits(&data(ext(0x0601F5D0), &[])), [false, true]);
        // ID12..0 and RTR are not compared.
        assert!(f.accepts(&data(ext(0x0300BFFF), &[])));
        assert!(f.accepts(&remote(ext(0x0601E000))));
        assert!(!f.accepts(&data(ext(0x0302A0F5), &[])));
        assert!(!f.accepts(&data(ext(0x0601F5D0 ^ (1 << 13)), &[])));
        // Don't care in filter 2 only: AMR3 = 0xFF opens ID20..13.
        let f = sja(Sja1000Mode::Dual, [0x18, 0x05, 0x30, 0x00], [0, 0, 0, 0xFF]);
        assert!(f.accepts(&data(ext(0x061FFFFF), &[])));
        assert!(!f.accepts(&data(ext(0x071FFFFF), &[])));
    }

    #[test]
    fn sja1000_dual_base_layout() {
        // Filter 1: ID 0x123, data frame, data byte 1 = 0x5A (ACR1 3:0 = 5, ACR3 3:0 = A).
        // Filter 2: ID 0x456 remote (ACR2 = 0x8A, ACR3 7:4 = 110 1).
        let f = sja(Sja1000Mode::Dual, [0x24, 0x65, 0x8A, 0xDA], [0, 0, 0, 0]);
        assert_eq!(f.hits(&data(base(0x123), &[0x5A, 0x00])), [true, false]);
        assert!(!f.accepts(&data(base(0x123), &[0x5B])), "low nibble in ACR3");
        assert!(!f.accepts(&data(base(0x123), &[0x4A])), "high nibble in ACR1");
        // No data byte: filter 1 decides on ID and RTR alone (data sheet 6.4.15.2).
        assert!(f.accepts(&data(base(0x123), &[])));
        assert!(!f.accepts(&remote(base(0x123))), "RTR compared in filter 1");
        assert_eq!(f.hits(&remote(base(0x456))), [false, true]);
        assert!(!f.accepts(&data(base(0x456), &[])), "RTR compared in filter 2");
        // Filter 2 ignores data entirely.
        assert!(f.accepts(&Frame::new_remote(base(0x456), 8).unwrap()));
        assert!(!f.accepts(&remote(base(0x457))));
        // Filter 2 here wants a remote 0x7FF, so filter 1 decides for 0x123 data frames.
        // Both data nibbles don't care:
        let f = sja(Sja1000Mode::Dual, [0x24, 0x65, 0xFF, 0xF0], [0, 0x0F, 0x00, 0x0F]);
        for b in 0..=0xFF {
            assert!(f.accepts(&data(base(0x123), &[b])));
        }
        assert!(!f.accepts(&data(base(0x7FF), &[0x5A])));
        assert!(f.accepts(&remote(base(0x7FF))));
        // Only the high nibble compared:
        let f = sja(Sja1000Mode::Dual, [0x24, 0x65, 0xFF, 0xF0], [0, 0x00, 0x00, 0x0F]);
        for b in 0..=0xFFu8 {
            assert_eq!(f.accepts(&data(base(0x123), &[b])), b >> 4 == 5, "{b:02X}");
        }
    }

    // --- SocketCAN -------------------------------------------------------------------------

    #[test]
    fn kernel_can_id_flags() {
        assert_eq!(kernel_can_id(&data(ext(0x0601F5D0), &[])), 0x8601_F5D0);
        assert_eq!(kernel_can_id(&remote(ext(0x0601F5D0))), 0xC601_F5D0);
        assert_eq!(kernel_can_id(&data(base(0x123), &[1])), 0x123);
        assert_eq!(kernel_can_id(&remote(base(0x7FF))), 0x4000_07FF);
    }

    #[test]
    fn socketcan_exact_and_masks() {
        let f = SocketCanFilter::exact(ext(0x0300A0F5));
        assert_eq!(f, SocketCanFilter::new(0x8300_A0F5, 0xDFFF_FFFF));
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])));
        assert!(!f.accepts(&remote(ext(0x0300A0F5))));
        assert!(!f.accepts(&data(ext(0x0300A0F4), &[])));
        assert!(!f.accepts(&data(base(0x0F5), &[])));

        let f = SocketCanFilter::exact(base(0x0F5));
        assert!(f.accepts(&data(base(0x0F5), &[])));
        assert!(!f.accepts(&data(ext(0x0F5), &[])), "EFF flag compared");

        // Without the EFF flag in the mask both formats pass on the low bits.
        let f = SocketCanFilter::new(0x0F5, CAN_SFF_MASK);
        assert!(f.accepts(&data(base(0x0F5), &[])));
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])));
        assert!(f.accepts(&remote(base(0x0F5))));

        // All frames from the monitor F5: source byte only, extended, any RTR.
        let f = SocketCanFilter::new(CAN_EFF_FLAG | 0xF5, CAN_EFF_FLAG | 0xFF);
        assert!(f.accepts(&data(ext(0x0300A0F5), &[])));
        assert!(f.accepts(&remote(ext(0x0601D0F5))));
        assert!(!f.accepts(&data(ext(0x0601F5D0), &[])));

        assert!(SocketCanFilter::accept_all().accepts(&remote(ext(0x1FFF_FFFF))));
    }

    #[test]
    fn socketcan_inversion() {
        let f = SocketCanFilter::exact(ext(0x0300A0F5)).inverted();
        assert_eq!(f.can_id & CAN_INV_FILTER, CAN_INV_FILTER);
        assert!(!f.accepts(&data(ext(0x0300A0F5), &[])));
        assert!(f.accepts(&remote(ext(0x0300A0F5))));
        assert!(f.accepts(&data(ext(0x0300F5A0), &[])));
        assert!(f.accepts(&data(base(0x0F5), &[])));
        assert_eq!(f.inverted(), SocketCanFilter::exact(ext(0x0300A0F5)));
        // An inverted accept-all filter passes nothing.
        let none = SocketCanFilter::accept_all().inverted();
        assert!(!none.accepts(&data(base(0x123), &[])));
    }

    #[test]
    fn socketcan_sff_only_mask_ignores_high_id_bits() {
        // EFF in the mask, not in can_id: af_can cuts the mask to SFF | EFF | RTR, so the bits
        // above ID10 in can_id drop out.
        let f = SocketCanFilter::new(0x0001_2345, CAN_EFF_FLAG | CAN_EFF_MASK);
        assert!(f.accepts(&data(base(0x345), &[])));
        assert!(!f.accepts(&data(ext(0x0001_2345), &[])));
        // The same with EFF in can_id is an ordinary extended filter.
        let f = SocketCanFilter::new(CAN_EFF_FLAG | 0x0001_2345, CAN_EFF_FLAG | CAN_EFF_MASK);
        assert!(f.accepts(&data(ext(0x0001_2345), &[])));
        assert!(!f.accepts(&data(base(0x345), &[])));
    }

    #[test]
    fn socketcan_error_filters() {
        // CAN_ERR_FLAG in the mask: an error-frame filter, never a data frame, even inverted.
        let f = SocketCanFilter::new(0, CAN_ERR_FLAG | 0x40);
        assert!(!f.accepts(&data(base(0x040), &[])));
        assert!(!f.inverted().accepts(&data(base(0x040), &[])));
        assert!(f.matches_can_id(CAN_ERR_FLAG | 0x40), "bus-off error frame");
        assert!(f.inverted().matches_can_id(CAN_ERR_FLAG | 0x40));
        assert!(!f.matches_can_id(CAN_ERR_FLAG | 0x20), "other class");
        // Ordinary filters never see error frames.
        assert!(!SocketCanFilter::accept_all().matches_can_id(CAN_ERR_FLAG | 0x40));
    }

    #[test]
    fn socketcan_filter_set_is_any_of() {
        let frame_a = data(ext(0x0300A0F5), &[]);
        let frame_b = data(ext(0x0601F5D0), &[]);
        let set = SocketCanFilterSet(vec![]);
        assert!(!set.accepts(&frame_a), "an empty set accepts nothing");
        let set = SocketCanFilterSet(vec![SocketCanFilter::exact(ext(0x0300A0F5))]);
        assert!(set.accepts(&frame_a) && !set.accepts(&frame_b));
        let set = SocketCanFilterSet(vec![
            SocketCanFilter::exact(ext(0x0300A0F5)),
            SocketCanFilter::exact(ext(0x0601F5D0)),
            SocketCanFilter::exact(ext(0x0601F5D0)),
        ]);
        assert!(set.accepts(&frame_a) && set.accepts(&frame_b));
        assert!(!set.accepts(&data(ext(0x0300F5A0), &[])));
    }

    // --- Atmel -----------------------------------------------------------------------------

    #[test]
    fn atmel_base_layout_and_masks() {
        assert_eq!(canidt_bytes(base(0x123), false), [0x24, 0x60, 0x00, 0x00]);
        assert_eq!(canidt_bytes(base(0x123), true), [0x24, 0x60, 0x00, 0x04]);
        assert_eq!(canidt_bytes(base(0x7FF), false), [0xFF, 0xE0, 0x00, 0x00]);

        let f = AtmelFilter::exact(base(0x123));
        assert_eq!(f.idm, [0xFF, 0xE0, 0x00, 0x05]);
        assert!(!f.ide && f.ide_mask);
        assert!(f.accepts(&data(base(0x123), &[1])));
        assert!(!f.accepts(&data(base(0x122), &[1])));
        assert!(!f.accepts(&remote(base(0x123))));
        assert!(!f.accepts(&data(ext(0x123 << 18), &[])), "IDE compared");

        // IDEMSK clear: an extended frame is compared in its own layout, where this IDM covers
        // ID28..18 only, so any extended identifier with those 11 bits passes.
        let open_ide = AtmelFilter { ide_mask: false, ..f };
        assert!(open_ide.accepts(&data(ext(0x123 << 18), &[])));
        assert!(open_ide.accepts(&data(ext((0x123 << 18) | 0x3FFFF), &[])));
        assert!(!open_ide.accepts(&data(ext(0x124 << 18), &[])));

        // RTRMSK clear: both data and remote frames.
        let any_rtr = AtmelFilter {
            idm: [0xFF, 0xE0, 0x00, 0x01],
            ..f
        };
        assert!(any_rtr.accepts(&remote(base(0x123))));
        // Remote frames only: RTRTAG set, RTRMSK set.
        let only_rtr = AtmelFilter {
            idt: canidt_bytes(base(0x123), true),
            ..f
        };
        assert!(only_rtr.accepts(&remote(base(0x123))));
        assert!(!only_rtr.accepts(&data(base(0x123), &[])));
    }

    #[test]
    fn atmel_mask_sense_is_compare_on_one() {
        // CANIDM = 0: nothing compared, every frame of the MOb's format passes.
        let f = AtmelFilter {
            idt: [0x18, 0x05, 0x07, 0xA8],
            idm: [0; 4],
            ide: true,
            ide_mask: true,
        };
        assert!(f.accepts(&data(ext(0x0601F5D0), &[])));
        assert!(f.accepts(&remote(ext(0))));
        assert!(!f.accepts(&data(base(0x0C0), &[])));
        // Compare the destination byte only (ID15..8 = CANIDT2 bits 2:0 and CANIDT3 bits 7:3).
        let f = AtmelFilter {
            idm: [0x00, 0x07, 0xF8, 0x00],
            ..f
        };
        for raw in harvester_ids() {
            assert_eq!(f.accepts(&data(ext(raw), &[])), (raw >> 8) & 0xFF == 0xA0);
        }
    }

    // --- property tests against bit-by-bit references --------------------------------------

    /// A frame's identifier bits, most significant first (29 or 11 of them).
    fn id_bits_msb_first(frame: &Frame) -> Vec<bool> {
        let n = if frame.is_extended() { 29 } else { 11 };
        (0..n).rev().map(|i| frame.raw_id() >> i & 1 == 1).collect()
    }

    fn byte_bits_msb_first(b: u8) -> Vec<bool> {
        (0..8).rev().map(|i| b >> i & 1 == 1).collect()
    }

    /// Bit `n` of a four-register image, counted from bit 7 of register 0 (n = 0) to bit 0 of
    /// register 3 (n = 31).
    fn reg_bit(regs: [u8; 4], n: usize) -> bool {
        regs[n / 8] >> (7 - n % 8) & 1 == 1
    }

    /// (position, message bit) pairs of each SJA1000 filter, transcribed from the data sheet's
    /// figures 9–12 (positions as in [`reg_bit`]).
    fn sja_reference_layout(mode: Sja1000Mode, frame: &Frame) -> Vec<Vec<(usize, bool)>> {
        let id = id_bits_msb_first(frame);
        let rtr = frame.is_remote();
        let d = frame.data();
        let at = |start: usize, bits: &[bool]| -> Vec<(usize, bool)> {
            bits.iter().enumerate().map(|(i, &b)| (start + i, b)).collect()
        };
        match (mode, frame.is_extended()) {
            (Sja1000Mode::Single, true) => {
                // ACR0..ACR3 7:3 = ID28..0, ACR3 bit 2 = RTR.
                let mut f = at(0, &id);
                f.push((29, rtr));
                vec![f]
            }
            (Sja1000Mode::Single, false) => {
                // ACR0 = ID10..3, ACR1 7:5 = ID2..0, ACR1 4 = RTR, ACR2 = data 1, ACR3 = data 2.
                let mut f = at(0, &id);
                f.push((11, rtr));
                if let Some(&b) = d.first() {
                    f.extend(at(16, &byte_bits_msb_first(b)));
                }
                if let Some(&b) = d.get(1) {
                    f.extend(at(24, &byte_bits_msb_first(b)));
                }
                vec![f]
            }
            (Sja1000Mode::Dual, true) => {
                // ID28..13 against ACR0:ACR1 and against ACR2:ACR3.
                vec![at(0, &id[..16]), at(16, &id[..16])]
            }
            (Sja1000Mode::Dual, false) => {
                let mut f1 = at(0, &id);
                f1.push((11, rtr));
                if let Some(&b) = d.first() {
                    let bits = byte_bits_msb_first(b);
                    f1.extend(at(12, &bits[..4])); // ACR1 3:0 = data 1 bits 7:4
                    f1.extend(at(28, &bits[4..])); // ACR3 3:0 = data 1 bits 3:0
                }
                let mut f2 = at(16, &id); // ACR2 = ID10..3, ACR3 7:5 = ID2..0
                f2.push((27, rtr)); // ACR3 bit 4 = RTR
                vec![f1, f2]
            }
        }
    }

    /// Accepted when, for at least one filter, every (message bit, code bit, mask bit) triple has
    /// mask = 1 (don't care) or message = code.
    fn sja_reference(f: &Sja1000Filter, frame: &Frame) -> bool {
        sja_reference_layout(f.mode, frame).iter().any(|filter| {
            filter
                .iter()
                .all(|&(n, msg)| reg_bit(f.amr, n) || reg_bit(f.acr, n) == msg)
        })
    }

    /// (position, message bit) pairs of the Atmel CANIDT layout: ID left-aligned from bit 7 of
    /// CANIDT1, RTRTAG at CANIDT4 bit 2 (position 29).
    fn atmel_reference(f: &AtmelFilter, frame: &Frame) -> bool {
        let mut triples: Vec<(bool, bool, bool)> = id_bits_msb_first(frame)
            .into_iter()
            .enumerate()
            .map(|(n, msg)| (msg, reg_bit(f.idt, n), reg_bit(f.idm, n)))
            .collect();
        triples.push((frame.is_remote(), reg_bit(f.idt, 29), reg_bit(f.idm, 29)));
        triples.push((frame.is_extended(), f.ide, f.ide_mask));
        // Here mask 1 = compare.
        triples.iter().all(|&(msg, tag, cmp)| !cmp || msg == tag)
    }

    /// The kernel's matching, bit by bit over the 32 bits of `can_id`.
    fn socketcan_reference(f: &SocketCanFilter, frame: &Frame) -> bool {
        let bit = |v: u32, i: usize| v >> i & 1 == 1;
        let id_len = if frame.is_extended() { 29 } else { 11 };
        let rx: Vec<bool> = (0..32)
            .map(|i| match i {
                31 => frame.is_extended(),
                30 => frame.is_remote(),
                29 => false, // never an error frame
                i if i < id_len => bit(frame.raw_id(), i),
                _ => false,
            })
            .collect();
        if bit(f.can_mask, 29) {
            return false; // an error-frame filter
        }
        let sff_only = bit(f.can_mask, 31) && !bit(f.can_id, 31);
        let all_equal = (0..32).all(|i| {
            let compared = bit(f.can_mask, i) && !(sff_only && (11..29).contains(&i));
            !compared || rx[i] == bit(f.can_id, i)
        });
        all_equal != bit(f.can_id, 29)
    }

    fn any_frame() -> impl Strategy<Value = Frame> {
        (
            any::<bool>(),
            any::<u32>(),
            any::<bool>(),
            proptest::collection::vec(any::<u8>(), 0..=8),
        )
            .prop_map(|(is_ext, raw, is_remote, bytes)| {
                let id = if is_ext {
                    ext(raw & 0x1FFF_FFFF)
                } else {
                    base((raw & 0x7FF) as u16)
                };
                if is_remote {
                    Frame::new_remote(id, bytes.len()).unwrap()
                } else {
                    Frame::new_data(id, &bytes).unwrap()
                }
            })
    }

    /// A sparse random word (about 1 bit in 16 set), to perturb a matching code.
    fn sparse() -> impl Strategy<Value = u32> {
        (any::<u32>(), any::<u32>(), any::<u32>(), any::<u32>()).prop_map(|(a, b, c, d)| a & b & c & d)
    }

    /// A mask that is dense, sparse or uniform, so that both outcomes occur often.
    fn any_mask() -> impl Strategy<Value = u32> {
        prop_oneof![
            any::<u32>(),
            sparse(),
            sparse().prop_map(|s| !s),
            Just(0u32),
            Just(u32::MAX),
        ]
    }

    fn set_bit(regs: &mut [u8; 4], n: usize, value: bool) {
        let m = 0x80 >> (n % 8);
        if value {
            regs[n / 8] |= m;
        } else {
            regs[n / 8] &= !m;
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn sja1000_matches_reference(
            frame in any_frame(),
            single in any::<bool>(),
            acr in any::<u32>(),
            amr in any_mask(),
            derive in any::<bool>(),
            pick in any::<usize>(),
            flips in sparse(),
        ) {
            let mode = if single { Sja1000Mode::Single } else { Sja1000Mode::Dual };
            let mut acr = acr.to_be_bytes();
            if derive {
                // Write one filter's message bits into the code, then disturb a few bits.
                let layout = sja_reference_layout(mode, &frame);
                for &(n, v) in &layout[pick % layout.len()] {
                    set_bit(&mut acr, n, v);
                }
                acr = (u32::from_be_bytes(acr) ^ flips).to_be_bytes();
            }
            let f = Sja1000Filter { mode, acr, amr: amr.to_be_bytes() };
            prop_assert_eq!(f.accepts(&frame), sja_reference(&f, &frame));
        }

        #[test]
        fn sja1000_single_exact_accepts_only_its_identifier(a in any_frame(), b in any_frame()) {
            let f = Sja1000Filter::single_exact(a.id());
            prop_assert_eq!(f.acr, acr_bytes_for(a.id(), false));
            prop_assert_eq!(f.accepts(&a), !a.is_remote());
            // Within one format the filter is exact; across formats see
            // `sja1000_single_exact_base_and_its_format_blindness`.
            if a.is_extended() == b.is_extended() {
                prop_assert_eq!(f.accepts(&b), b.id() == a.id() && !b.is_remote());
            }
        }

        #[test]
        fn atmel_matches_reference(
            frame in any_frame(),
            idt in any::<u32>(),
            idm in any_mask(),
            ide in any::<bool>(),
            ide_mask in any::<bool>(),
            derive in any::<bool>(),
            flips in sparse(),
        ) {
            let idt = if derive {
                u32::from_be_bytes(canidt_bytes(frame.id(), frame.is_remote())) ^ flips
            } else {
                idt
            };
            let f = AtmelFilter { idt: idt.to_be_bytes(), idm: idm.to_be_bytes(), ide, ide_mask };
            prop_assert_eq!(f.accepts(&frame), atmel_reference(&f, &frame));
        }

        #[test]
        fn atmel_exact_accepts_only_its_identifier(a in any_frame(), b in any_frame()) {
            let f = AtmelFilter::exact(a.id());
            prop_assert_eq!(f.accepts(&a), !a.is_remote());
            prop_assert_eq!(f.accepts(&b), b.id() == a.id() && !b.is_remote());
        }

        #[test]
        fn socketcan_matches_reference(
            frame in any_frame(),
            can_id in any::<u32>(),
            can_mask in any_mask(),
            derive in any::<bool>(),
            invert in any::<bool>(),
            flips in sparse(),
        ) {
            let can_id = if derive { kernel_can_id(&frame) ^ flips } else { can_id };
            let can_id = if invert { can_id | CAN_INV_FILTER } else { can_id & !CAN_INV_FILTER };
            let f = SocketCanFilter::new(can_id, can_mask);
            prop_assert_eq!(f.accepts(&frame), socketcan_reference(&f, &frame));
            prop_assert_eq!(f.inverted().accepts(&frame) != f.accepts(&frame), can_mask & CAN_ERR_FLAG == 0);
        }

        #[test]
        fn socketcan_set_is_any_of_its_filters(
            frame in any_frame(),
            filters in proptest::collection::vec((any::<u32>(), any_mask()), 0..4),
        ) {
            let set = SocketCanFilterSet(
                filters.iter().map(|&(id, mask)| SocketCanFilter::new(id, mask)).collect(),
            );
            let any = set.0.iter().any(|f| socketcan_reference(f, &frame));
            prop_assert_eq!(set.accepts(&frame), any);
        }
    }
}
