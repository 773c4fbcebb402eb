//! A point list's `direction` column: the direction of approach of each point, where the order
//! of the points cannot show it (a target reached by overshooting it and coming back).
//!
//! The column is named `direction`, `dir` or `approach` (any case). A cell holds `+`, `+1`, `1`,
//! `up`, `increasing`, `forward`, `fwd`, `pos` or `↑` for a point reached with increasing DUT
//! readings; `-`, `−`, `-1`, `down`, `decreasing`, `backward`, `back`, `bwd`, `neg` or `↓` for
//! one reached with decreasing readings (any case); an empty cell leaves the point's direction
//! to the order of the points. In a timed log the direction comes from the motion, and a column
//! of that name is a channel like any other.

use calib_core::reference_points::Approach;

/// Whether a column of a point list named `name` holds the points' directions of approach.
pub fn is_direction_column(name: &str) -> bool {
    ["direction", "dir", "approach"]
        .iter()
        .any(|n| name.trim().eq_ignore_ascii_case(n))
}

/// A cell that names no direction of approach (the reader's error says what to write,
/// [`EXPECTED`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotADirection;

/// The direction a cell states: `Ok(None)` for an empty cell (see the [module docs](self)).
pub fn parse(cell: &[u8]) -> Result<Option<Approach>, NotADirection> {
    let text = std::str::from_utf8(cell).map_err(|_| NotADirection)?.trim();
    let word = text.to_ascii_lowercase();
    match word.as_str() {
        "" => Ok(None),
        "+" | "+1" | "1" | "up" | "increasing" | "forward" | "fwd" | "pos" | "↑" => {
            Ok(Some(Approach::Increasing))
        }
        "-" | "−" | "-1" | "down" | "decreasing" | "backward" | "back" | "bwd" | "neg" | "↓" => {
            Ok(Some(Approach::Decreasing))
        }
        _ => Err(NotADirection),
    }
}

/// What to write instead of a cell that names no direction.
pub const EXPECTED: &str = "write `+` or `-` (also 1/-1, up/down, increasing/decreasing, \
                            forward/backward) for a point reached with increasing or decreasing \
                            DUT readings, or leave the cell empty to take the direction from the \
                            order of the points";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_name_directions() {
        for (cell, want) in [
            ("+", Some(Approach::Increasing)),
            (" Up ", Some(Approach::Increasing)),
            ("FORWARD", Some(Approach::Increasing)),
            ("1", Some(Approach::Increasing)),
            ("↑", Some(Approach::Increasing)),
            ("-", Some(Approach::Decreasing)),
            ("−", Some(Approach::Decreasing)),
            ("-1", Some(Approach::Decreasing)),
            ("Backward", Some(Approach::Decreasing)),
            ("down", Some(Approach::Decreasing)),
            ("", None),
            ("  ", None),
        ] {
            assert_eq!(parse(cell.as_bytes()), Ok(want), "{cell:?}");
        }
        for cell in ["0", "2", "left", "cw", "+-", "\u{ff}"] {
            assert_eq!(parse(cell.as_bytes()), Err(NotADirection), "{cell:?}");
        }
        assert!(is_direction_column(" Direction"));
        assert!(is_direction_column("DIR"));
        assert!(!is_direction_column("direction_deg"));
    }
}
