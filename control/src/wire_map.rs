//! The force map of an `N`-wire device at one thimble position (paper eqs. 3-5).
//!
//! Column `i` of the pull matrix `V = J^-T` is the unit vector `u_i = -v_i` along which wire `i`
//! pulls the thimble (towards its guide); the force of tensions `t` is `f = V t` (eq. 4) and the
//! tensions that make a force are `t = J^T f = V^-1 f` (eq. 5). Row `k` of `J^T` is orthogonal to
//! every wire but `k`: it is the (unnormalised) inward normal of the face of the wire cone opposite
//! wire `k`, which makes the bisector and the isotropic force limit one-liners.
//!
//! `N` is the number of wires *and* the dimension of the force space: 2 for the planar device of
//! the paper's experiments (x-z plane), 3 for the wearable device.

use nalgebra::{Matrix2, Matrix3, SMatrix, SVector};

/// Smallest `|det V|` accepted: below it the wires are (nearly) coplanar/collinear and the
/// thimble is on the guide plane, where the device cannot hold it.
pub const MIN_PULL_DETERMINANT: f64 = 1e-9;

/// The force map at one thimble position. Built by a rig (`Rig3::wire_map`,
/// `RigPlanar::wire_map`); only invertible maps exist.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireMap<const N: usize> {
    pull: SMatrix<f64, N, N>,
    tension_of_force: SMatrix<f64, N, N>,
}

impl WireMap<2> {
    /// A planar map from its pull matrix (columns: unit pull directions). `None` when singular
    /// or not finite.
    pub fn from_pull(pull: Matrix2<f64>) -> Option<WireMap<2>> {
        if !pull.iter().all(|c| c.is_finite()) || pull.determinant().abs() < MIN_PULL_DETERMINANT {
            return None;
        }
        let tension_of_force = pull.try_inverse()?;
        Some(WireMap {
            pull,
            tension_of_force,
        })
    }
}

impl WireMap<3> {
    /// A spatial map from its pull matrix (columns: unit pull directions). `None` when singular
    /// or not finite.
    pub fn from_pull(pull: Matrix3<f64>) -> Option<WireMap<3>> {
        if !pull.iter().all(|c| c.is_finite()) || pull.determinant().abs() < MIN_PULL_DETERMINANT {
            return None;
        }
        let tension_of_force = pull.try_inverse()?;
        Some(WireMap {
            pull,
            tension_of_force,
        })
    }
}

impl<const N: usize> WireMap<N> {
    /// `V = J^-T`, columns are the unit pull directions `-v_i`.
    pub fn pull_matrix(&self) -> &SMatrix<f64, N, N> {
        &self.pull
    }

    /// `J^T = V^-1`: maps a force to the tensions that make it.
    pub fn tension_matrix(&self) -> &SMatrix<f64, N, N> {
        &self.tension_of_force
    }

    /// Unit vector along which wire `i` pulls the thimble (`-v_i`).
    pub fn pull_direction(&self, wire: usize) -> SVector<f64, N> {
        self.pull.column(wire).into_owned()
    }

    /// The force made by tensions `tensions_n` (eq. 4), newtons.
    pub fn force(&self, tensions_n: &[f64; N]) -> SVector<f64, N> {
        self.pull * SVector::<f64, N>::from_column_slice(tensions_n)
    }

    /// The tensions that make `force_n` exactly (eq. 5); may be negative.
    pub fn tensions(&self, force_n: &SVector<f64, N>) -> [f64; N] {
        let t = self.tension_of_force * force_n;
        let mut out = [0.0; N];
        out.copy_from_slice(t.as_slice());
        out
    }

    /// `|row_k(J^T)|`: a force `f` changes the tension of wire `k` by at most `|f|` times this.
    pub fn tension_gain(&self, wire: usize) -> f64 {
        self.tension_of_force.row(wire).norm()
    }

    /// The direction inside the wire cone that is equally far (in angle) from every face of the
    /// cone: the axis of the widest circular cone that fits inside it.
    ///
    /// For two wires this is the bisector of the vertex angle (paper, algorithm F2). For three
    /// wires it is the 3D analogue with the same property the paper uses the bisector for: a
    /// field along it maximises the radius of the sphere `S_f` of forces renderable exactly in
    /// every direction (it is `V w` with `w_k = |row_k(J^T)|`, because row `k` of `J^T` is the
    /// inward normal of the face opposite wire `k`). It differs from the plain mean of the wire
    /// directions when the cone is not symmetric; see [`WireMap::mean_pull_direction`].
    pub fn bisector(&self) -> SVector<f64, N> {
        let mut w = SVector::<f64, N>::zeros();
        for k in 0..N {
            w[k] = self.tension_gain(k);
        }
        let d = self.pull * w;
        let norm = d.norm();
        if norm > 1e-12 && norm.is_finite() {
            d / norm
        } else {
            self.mean_pull_direction()
        }
    }

    /// The normalised sum of the wires' unit pull directions (equals the bisector for two wires).
    pub fn mean_pull_direction(&self) -> SVector<f64, N> {
        let mut d = SVector::<f64, N>::zeros();
        for i in 0..N {
            d += self.pull.column(i);
        }
        let norm = d.norm();
        if norm > 1e-12 && norm.is_finite() {
            d / norm
        } else {
            d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn planar_bisector_is_the_sum_of_unit_pulls() {
        let u0 = Vector2::new(-1.0, -2.0).normalize();
        let u1 = Vector2::new(3.0, -1.0).normalize();
        let map = WireMap::<2>::from_pull(Matrix2::from_columns(&[u0, u1])).unwrap();
        let b = map.bisector();
        assert!((b - (u0 + u1).normalize()).norm() < 1e-12);
        assert!((b.dot(&u0) - b.dot(&u1)).abs() < 1e-12);
    }

    #[test]
    fn spatial_bisector_is_equidistant_from_the_faces() {
        let u = [
            Vector3::new(-0.6, -0.1, -0.8).normalize(),
            Vector3::new(0.7, -0.3, -0.6).normalize(),
            Vector3::new(0.05, 0.9, -0.4).normalize(),
        ];
        let map = WireMap::<3>::from_pull(Matrix3::from_columns(&u)).unwrap();
        let d = map.bisector();
        // Distance (sine of the angle) from d to each face plane spanned by two wires.
        let sines: [f64; 3] = core::array::from_fn(|k| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            d.dot(&u[i].cross(&u[j]).normalize()).abs()
        });
        assert!((sines[0] - sines[1]).abs() < 1e-12 && (sines[1] - sines[2]).abs() < 1e-12);
        let t = map.tensions(&d);
        assert!(t.iter().all(|&x| x > 0.0), "inside the cone");
    }

    #[test]
    fn singular_maps_are_refused() {
        let u = Vector3::new(1.0, 0.0, 0.0);
        assert!(WireMap::<3>::from_pull(Matrix3::from_columns(&[u, u, -u])).is_none());
        assert!(WireMap::<2>::from_pull(Matrix2::new(1.0, f64::NAN, 0.0, 1.0)).is_none());
    }
}
