//! # videt-can-timing — how long a classical CAN frame occupies the bus (pure, allocation-free)
//!
//! A classical (CAN 2.0A, standard-identifier) data frame on the wire is: start of frame (1),
//! identifier (11), RTR (1), IDE (1), r0 (1), DLC (4), data (8 x DLC), CRC-15 (15) — the
//! *stuffed* region, where the transmitter inserts a complement bit after five equal bits —
//! then CRC delimiter (1), ACK slot and delimiter (2), end of frame (7) and the intermission
//! (3) before the next frame may start. So a frame is `47 + 8·n` bits plus its stuff bits;
//! the stuffed region of `34 + 8·n` bits holds at most `⌊(34 + 8·n − 1) / 4⌋` of them.
//!
//! [`frame_bits`] gives the exact length of a given frame (its CRC and stuffing computed);
//! [`nominal_bits`] and [`worst_case_bits`] bound every frame of a given length; [`BusLoad`] is
//! the share of the bus a traffic pattern takes. Used by the configuration check (what the
//! configured bus can carry) and by the digital twin's bus (when each frame arrives).
#![forbid(unsafe_code)]
#![no_std]
#![warn(missing_docs)]

/// Bits of a standard data frame outside the data field, without stuffing: SOF, identifier,
/// RTR, IDE, r0, DLC, CRC, CRC delimiter, ACK slot and delimiter, EOF, intermission.
const OVERHEAD_BITS: u32 = 47;
/// Bits of the stuffed region outside the data field: SOF, identifier, RTR, IDE, r0, DLC, CRC.
const STUFFED_OVERHEAD_BITS: u32 = 34;

/// Length in bits of a standard data frame with `dlc` data bytes, without stuff bits.
pub const fn nominal_bits(dlc: u8) -> u32 {
    OVERHEAD_BITS + 8 * dlc as u32
}

/// The most stuff bits a standard data frame with `dlc` data bytes can carry.
pub const fn max_stuff_bits(dlc: u8) -> u32 {
    (STUFFED_OVERHEAD_BITS + 8 * dlc as u32 - 1) / 4
}

/// Length in bits of the longest standard data frame with `dlc` data bytes (every possible
/// stuff bit inserted): 55 bits for an empty frame, 135 for eight bytes.
pub const fn worst_case_bits(dlc: u8) -> u32 {
    nominal_bits(dlc) + max_stuff_bits(dlc)
}

/// CAN's CRC-15 (polynomial 0x4599) over a sequence of bits.
fn crc15(bits: impl Iterator<Item = bool>) -> u16 {
    let mut crc: u16 = 0;
    for bit in bits {
        let feedback = bit ^ (crc & 0x4000 != 0);
        crc = (crc << 1) & 0x7FFF;
        if feedback {
            crc ^= 0x4599;
        }
    }
    crc
}

/// The bits of the stuffed region before the CRC (SOF through data), most significant first.
fn header_and_data_bits(id: u16, data: &[u8]) -> impl Iterator<Item = bool> + '_ {
    let dlc = data.len() as u16;
    let sof = core::iter::once(false);
    let ident = (0..11).rev().map(move |b| id >> b & 1 != 0);
    // RTR = 0 (data frame), IDE = 0 (standard), r0 = 0.
    let control = [false, false, false].into_iter();
    let length = (0..4).rev().map(move |b| dlc >> b & 1 != 0);
    let payload = data
        .iter()
        .flat_map(|byte| (0..8).rev().map(move |b| byte >> b & 1 != 0));
    sof.chain(ident).chain(control).chain(length).chain(payload)
}

/// Stuff bits a transmitter inserts into `bits`: one after every run of five equal bits,
/// counting the inserted bit as the start of the next run.
fn stuff_bit_count(bits: impl Iterator<Item = bool>) -> u32 {
    let mut stuffed = 0;
    let mut last = None;
    let mut run = 0;
    for bit in bits {
        if Some(bit) == last {
            run += 1;
        } else {
            last = Some(bit);
            run = 1;
        }
        if run == 5 {
            stuffed += 1;
            last = Some(!bit);
            run = 1;
        }
    }
    stuffed
}

/// Exact length in bits (stuffing included, intermission included) of the standard data frame
/// with identifier `id` (11 bits; higher bits are ignored) and `data` (at most 8 bytes; more
/// are ignored).
pub fn frame_bits(id: u16, data: &[u8]) -> u32 {
    let id = id & 0x7FF;
    let data = &data[..data.len().min(8)];
    let crc = crc15(header_and_data_bits(id, data));
    let crc_bits = (0..15).rev().map(move |b| crc >> b & 1 != 0);
    let stuffed = stuff_bit_count(header_and_data_bits(id, data).chain(crc_bits));
    nominal_bits(data.len() as u8) + stuffed
}

/// Time on a bus of `bitrate` bit/s for `bits` bits, in nanoseconds (rounded up).
pub const fn bits_to_ns(bits: u32, bitrate: u32) -> u64 {
    (bits as u64 * 1_000_000_000).div_ceil(bitrate as u64)
}

/// The traffic a bus carries: frames sent every control period and frames sent on their own
/// timers (heartbeats), by data length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusLoad {
    /// Bits per second without stuffing.
    pub nominal_bits_per_s: f64,
    /// Bits per second with every possible stuff bit.
    pub worst_case_bits_per_s: f64,
    /// The bus's bit rate.
    pub bitrate: u32,
    /// Bus time per control period for the cyclic frames, worst case, seconds.
    pub worst_case_cycle_s: f64,
}

impl BusLoad {
    /// The load of `cyclic` frames (data lengths) sent every period of `rate_hz`, plus
    /// `timed` frames `(data length, interval in seconds)`, on a bus of `bitrate` bit/s.
    pub fn of(rate_hz: f64, cyclic: &[u8], timed: &[(u8, f64)], bitrate: u32) -> BusLoad {
        let per_cycle = |f: fn(u8) -> u32| cyclic.iter().map(|&d| f64::from(f(d))).sum::<f64>();
        let timed_rate = |f: fn(u8) -> u32| {
            timed
                .iter()
                .filter(|(_, every)| *every > 0.0)
                .map(|&(d, every)| f64::from(f(d)) / every)
                .sum::<f64>()
        };
        let worst_cycle_bits = per_cycle(worst_case_bits);
        BusLoad {
            nominal_bits_per_s: per_cycle(nominal_bits) * rate_hz + timed_rate(nominal_bits),
            worst_case_bits_per_s: worst_cycle_bits * rate_hz + timed_rate(worst_case_bits),
            bitrate,
            worst_case_cycle_s: worst_cycle_bits / f64::from(bitrate.max(1)),
        }
    }

    /// Fraction of the bus's time taken without stuffing.
    pub fn nominal(&self) -> f64 {
        self.nominal_bits_per_s / f64::from(self.bitrate.max(1))
    }

    /// Fraction of the bus's time taken with every possible stuff bit.
    pub fn worst_case(&self) -> f64 {
        self.worst_case_bits_per_s / f64::from(self.bitrate.max(1))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;
    use std::vec;
    use std::vec::Vec;

    /// An independent oracle: build the stuffed frame as a bit vector, as a transmitter would.
    fn transmitted_frame(id: u16, data: &[u8]) -> Vec<bool> {
        let mut raw = vec![false]; // SOF
        raw.extend((0..11).rev().map(|b| (id >> b) & 1 == 1));
        raw.extend([false, false, false]);
        raw.extend((0..4).rev().map(|b| (data.len() >> b) & 1 == 1));
        for byte in data {
            raw.extend((0..8).rev().map(|b| (byte >> b) & 1 == 1));
        }
        let mut reg = 0u32;
        for &bit in &raw {
            let top = (reg >> 14) & 1 == 1;
            reg = (reg << 1) & 0x7FFF;
            if bit ^ top {
                reg ^= 0x4599;
            }
        }
        raw.extend((0..15).rev().map(|b| (reg >> b) & 1 == 1));
        let mut out = Vec::new();
        let mut same = 0;
        for &bit in &raw {
            if out.last() == Some(&bit) {
                same += 1;
            } else {
                same = 1;
            }
            out.push(bit);
            if same == 5 {
                out.push(!bit);
                same = 1;
            }
        }
        // CRC delimiter, ACK slot (recessive as sent), ACK delimiter, EOF, intermission.
        out.extend([true; 1 + 1 + 1 + 7 + 3]);
        out
    }

    #[test]
    fn the_bounds_are_the_textbook_figures() {
        assert_eq!(nominal_bits(0), 47);
        assert_eq!(worst_case_bits(0), 55);
        assert_eq!(nominal_bits(8), 111);
        assert_eq!(worst_case_bits(8), 135);
        assert_eq!(worst_case_bits(4), 95);
    }

    #[test]
    fn an_all_zero_frame_is_stuffed_after_every_five_zeros() {
        // SOF + 11 zero id bits + RTR/IDE/r0 + DLC 0 = 19 dominant bits, then the CRC of
        // zeros (zero): 34 zero bits, a recessive stuff bit after every five of them.
        assert_eq!(frame_bits(0, &[]), 47 + 6);
    }

    #[test]
    fn no_one_byte_frame_exceeds_the_worst_case_bound() {
        // Every identifier and data byte: the bound holds (it is conservative: the fixed
        // RTR/IDE/r0 bits and the CRC keep real frames a few bits below it).
        let longest = (0u16..0x800)
            .flat_map(|id| (0u16..=255).map(move |b| frame_bits(id, &[b as u8])))
            .max()
            .unwrap();
        assert!(longest <= worst_case_bits(1), "{longest}");
        assert!(
            longest > nominal_bits(1) + max_stuff_bits(1) / 2,
            "{longest}"
        );
    }

    #[test]
    fn the_sync_frame_length_matches_the_transmitted_bits() {
        assert_eq!(
            frame_bits(0x080, &[]) as usize,
            transmitted_frame(0x080, &[]).len()
        );
    }

    proptest! {
        #[test]
        fn exact_length_matches_an_independent_transmitter_and_stays_in_bounds(
            id in 0u16..0x800,
            data in proptest::collection::vec(any::<u8>(), 0..=8),
        ) {
            let bits = frame_bits(id, &data);
            prop_assert_eq!(bits as usize, transmitted_frame(id, &data).len());
            let dlc = data.len() as u8;
            prop_assert!(bits >= nominal_bits(dlc) && bits <= worst_case_bits(dlc));
        }
    }

    #[test]
    fn bus_time_rounds_up_to_the_nanosecond() {
        assert_eq!(bits_to_ns(135, 1_000_000), 135_000);
        assert_eq!(bits_to_ns(1, 3), 333_333_334);
    }

    #[test]
    fn four_kilohertz_of_three_drives_overloads_a_megabit_bus() {
        // SYNC, then per drive a 4-byte command and an 8-byte feedback frame.
        let cyclic = [0, 4, 8, 4, 8, 4, 8];
        let at_1k = BusLoad::of(1000.0, &cyclic, &[], 1_000_000);
        assert!((at_1k.nominal() - 0.617).abs() < 1e-9);
        assert!((at_1k.worst_case() - 0.745).abs() < 1e-9);
        assert!((at_1k.worst_case_cycle_s - 745e-6).abs() < 1e-12);
        let at_4k = BusLoad::of(4000.0, &cyclic, &[(1, 0.1)], 1_000_000);
        assert!(at_4k.worst_case() > 2.9, "{}", at_4k.worst_case());
    }
}
