//! The control algorithms (paper section 5): which force field each adds to the contact force
//! and which projection maps a force outside the reachable set into it.

/// Control algorithm: which force field is added to the contact force and how the sum is
/// projected onto `F`.
///
/// | algorithm | field `f_c` (magnitude from the parameters)       | projection outside `F` |
/// |-----------|---------------------------------------------------|------------------------|
/// | `P1`      | constant direction (paper: `|f_c| = 0`)           | P1: clamp negatives    |
/// | `P2`      | constant direction (paper: `|f_c| = 0`)           | P2: along `n` first    |
/// | `F1`      | constant direction                                | P2                     |
/// | `F2`      | along the bisector of the wire cone               | P2                     |
/// | `Qp`      | along the bisector of the wire cone               | normal-weighted nearest|
///
/// The paper defines F1 and F2 by their field only and leaves the projection open; P2 is used
/// because it is the better of the paper's two (its Fig. 21 against Fig. 20). P1 and P2 accept a
/// field because the paper's Figs. 20-21 run them with `|f_c|` up to 2 N. Every projection is
/// continuous in the force and the pose and keeps the felt bound (`docs/felt-force.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algorithm {
    /// P1: negative tensions set to `t_min`, the positive ones actuated as computed.
    P1,
    /// P2: from P1's tensions, the least change along the wires that makes the force along
    /// `n = f/|f|` as close to `|f|` as a weight on the normal allows (the paper's
    /// `t' = (n^T V_P)^+ r`, made continuous where the pulling wires change).
    #[default]
    P2,
    /// F1: constant force field `f_c` of fixed direction added, then P2.
    F1,
    /// F2: force field of constant magnitude along the bisector of the wires, then P2.
    F2,
    /// QP: bisector field, then the reachable force nearest the desired one, the error along
    /// `n` weighed 101 times the error across it (nearly exact along `n` where the wires can
    /// do it). Exact small active-set solution over the `3^N` bound patterns.
    Qp,
}

/// How a target force outside `F` is mapped into `F`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Projection {
    /// Paper's P1: `t = clamp(J^T f, t_min, t_max)`.
    ClampNegative,
    /// Paper's P2, continuous: P1 corrected towards the force along the normal.
    ExactAlongNormal,
    /// Nearest in force, the normal component weighed most.
    NormalFirstNearest,
}

/// Where the force field points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldRule {
    /// A fixed direction in the workspace (the parameters'), e.g. `-z`: towards the frame.
    Constant,
    /// Along the bisector of the wire cone at the current position ([`WireMap::bisector`](crate::WireMap::bisector)).
    Bisector,
}

/// Names accepted by [`Algorithm::from_name`].
pub const ALGORITHM_NAMES: [&str; 5] = ["P1", "P2", "F1", "F2", "QP"];

impl Algorithm {
    /// Every algorithm, in the paper's order then ours.
    pub const ALL: [Algorithm; 5] = [
        Algorithm::P1,
        Algorithm::P2,
        Algorithm::F1,
        Algorithm::F2,
        Algorithm::Qp,
    ];

    /// The projection this algorithm uses outside `F`.
    pub fn projection(self) -> Projection {
        match self {
            Algorithm::P1 => Projection::ClampNegative,
            Algorithm::P2 | Algorithm::F1 | Algorithm::F2 => Projection::ExactAlongNormal,
            Algorithm::Qp => Projection::NormalFirstNearest,
        }
    }

    /// Where this algorithm's force field points.
    pub fn field_rule(self) -> FieldRule {
        match self {
            Algorithm::P1 | Algorithm::P2 | Algorithm::F1 => FieldRule::Constant,
            Algorithm::F2 | Algorithm::Qp => FieldRule::Bisector,
        }
    }

    /// Short name (`"P1"`, ..., `"QP"`).
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::P1 => "P1",
            Algorithm::P2 => "P2",
            Algorithm::F1 => "F1",
            Algorithm::F2 => "F2",
            Algorithm::Qp => "QP",
        }
    }

    /// Parse a short name, case-insensitive.
    pub fn from_name(name: &str) -> Option<Algorithm> {
        Algorithm::ALL
            .into_iter()
            .find(|a| a.name().eq_ignore_ascii_case(name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for a in Algorithm::ALL {
            assert_eq!(Algorithm::from_name(a.name()), Some(a));
        }
        assert_eq!(Algorithm::from_name("qp"), Some(Algorithm::Qp));
        assert_eq!(Algorithm::from_name("P3"), None);
    }
}
