//! The three intensity levels a colour channel is rendered with (paper §6.1: "only levels Low,
//! Middle and High are allowed"), and the 27 level triples.

use videt_hal::VIBROTACTORS;

/// One channel's level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Level {
    /// Low: the vibrotactor is silent.
    Low = 0,
    /// Middle.
    Mid = 1,
    /// High.
    High = 2,
}

/// One level per channel, in the order red, green, blue (= vibrotactor 0, 1, 2).
pub type LevelTriple = [Level; VIBROTACTORS];

impl Level {
    /// All levels, lowest first.
    pub const ALL: [Level; 3] = [Level::Low, Level::Mid, Level::High];

    /// `0`, `1` or `2`.
    pub const fn index(self) -> u8 {
        self as u8
    }

    /// The level with this index, `None` above 2.
    pub const fn from_index(index: u8) -> Option<Level> {
        match index {
            0 => Some(Level::Low),
            1 => Some(Level::Mid),
            2 => Some(Level::High),
            _ => None,
        }
    }

    /// Lower-case name used by the tool and the status line: `low`, `mid`, `high`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Level::Low => "low",
            Level::Mid => "mid",
            Level::High => "high",
        }
    }

    /// One-letter name: `L`, `M`, `H`.
    pub const fn letter(self) -> char {
        match self {
            Level::Low => 'L',
            Level::Mid => 'M',
            Level::High => 'H',
        }
    }

    /// The 8-bit value that displays this level in a level-colour image (0, 128, 255).
    pub const fn display_value(self) -> u8 {
        match self {
            Level::Low => 0,
            Level::Mid => 128,
            Level::High => 255,
        }
    }

    /// Parse `low`/`mid`/`high` or `L`/`M`/`H` (case-insensitive).
    pub fn parse(text: &str) -> Option<Level> {
        match text.to_ascii_lowercase().as_str() {
            "l" | "low" => Some(Level::Low),
            "m" | "mid" | "middle" => Some(Level::Mid),
            "h" | "high" => Some(Level::High),
            _ => None,
        }
    }
}

impl core::fmt::Display for Level {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The colour that displays a level triple (one of 27): each channel 0, 128 or 255.
pub fn level_colour(levels: LevelTriple) -> [u8; 3] {
    levels.map(Level::display_value)
}

/// The triple as three letters, e.g. `HML` (red High, green Mid, blue Low).
pub fn triple_letters(levels: LevelTriple) -> [char; 3] {
    levels.map(Level::letter)
}

/// Parse three letters such as `HML` into a triple.
pub fn parse_triple(letters: &str) -> Option<LevelTriple> {
    let mut chars = letters.chars();
    let mut out = [Level::Low; 3];
    for slot in &mut out {
        *slot = Level::parse(chars.next()?.encode_utf8(&mut [0; 4]))?;
    }
    if chars.next().is_some() {
        return None;
    }
    Some(out)
}

/// Encode a triple in one byte (`0..27`, base 3, red most significant), for lock-free hand-over
/// through an `AtomicU8`.
pub const fn encode_triple(levels: LevelTriple) -> u8 {
    levels[0].index() * 9 + levels[1].index() * 3 + levels[2].index()
}

/// Decode a byte written by [`encode_triple`]; `None` for anything outside `0..27`.
pub const fn decode_triple(code: u8) -> Option<LevelTriple> {
    if code >= 27 {
        return None;
    }
    match (
        Level::from_index(code / 9),
        Level::from_index(code / 3 % 3),
        Level::from_index(code % 3),
    ) {
        (Some(r), Some(g), Some(b)) => Some([r, g, b]),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_triple_round_trips_through_its_code() {
        let mut seen = [false; 27];
        for r in Level::ALL {
            for g in Level::ALL {
                for b in Level::ALL {
                    let code = encode_triple([r, g, b]);
                    assert!(!seen[code as usize], "codes are distinct");
                    seen[code as usize] = true;
                    assert_eq!(decode_triple(code), Some([r, g, b]));
                }
            }
        }
        assert_eq!(decode_triple(27), None);
        assert_eq!(decode_triple(255), None);
    }

    #[test]
    fn names_and_letters_parse_back() {
        for l in Level::ALL {
            assert_eq!(Level::parse(l.as_str()), Some(l));
            assert_eq!(Level::parse(&l.letter().to_string()), Some(l));
        }
        assert_eq!(
            parse_triple("HmL"),
            Some([Level::High, Level::Mid, Level::Low])
        );
        assert_eq!(parse_triple("HM"), None);
        assert_eq!(parse_triple("HMLL"), None);
        assert_eq!(parse_triple("HXL"), None);
        assert_eq!(
            level_colour([Level::High, Level::Mid, Level::Low]),
            [255, 128, 0]
        );
    }
}
