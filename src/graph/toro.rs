//! TORO 3D lines: `VERTEX3 id x y z roll pitch yaw` and
//! `EDGE3 i j x y z roll pitch yaw I11 I12 … I16 I22 … I66`.
//!
//! The rotation is `Rz(yaw) · Ry(pitch) · Rx(roll)`. The 21 information entries are the
//! upper triangle, row by row, in the order **(x, y, z, roll, pitch, yaw)**; they are
//! converted to and from the graph's (rotation, translation) order here.

use super::file::{parse_fields, LineError, Tokens};
use super::se3;
use nalgebra::{Isometry3, Matrix6, Translation3};

/// Permutation between TORO order (x y z roll pitch yaw) and GTSAM order (rotation,
/// translation): GTSAM index `k` holds TORO index `TORO_OF_GTSAM[k]`.
const TORO_OF_GTSAM: [usize; 6] = [3, 4, 5, 0, 1, 2];

/// Parses the fields after `VERTEX3`: id and pose.
pub fn parse_vertex(tokens: &mut Tokens<'_>) -> Result<(u64, Isometry3<f64>), LineError> {
    let id = tokens.id("vertex id")?;
    let v: [f64; 6] = parse_fields(tokens, "VERTEX3")?;
    tokens.finish("VERTEX3")?;
    Ok((id, pose_from_xyzrpy(&v)))
}

/// Parses the fields after `EDGE3`: ids, measurement and information in GTSAM order.
pub fn parse_edge(
    tokens: &mut Tokens<'_>,
) -> Result<(u64, u64, Isometry3<f64>, Matrix6<f64>), LineError> {
    let i = tokens.id("first vertex id")?;
    let j = tokens.id("second vertex id")?;
    let v: [f64; 6] = parse_fields(tokens, "EDGE3")?;
    let upper: [f64; 21] = parse_fields(tokens, "EDGE3 information")?;
    tokens.finish("EDGE3")?;
    Ok((
        i,
        j,
        pose_from_xyzrpy(&v),
        permute_information(&segloc_maps::landmark::from_upper_triangle6(&upper), false),
    ))
}

/// Formats a `VERTEX3` line.
pub fn format_vertex(id: u64, pose: &Isometry3<f64>) -> String {
    let t = pose.translation.vector;
    let (r, p, y) = se3::rpy_from_rotation(&pose.rotation);
    format!("VERTEX3 {id} {} {} {} {r} {p} {y}", t.x, t.y, t.z)
}

/// Formats an `EDGE3` line from a measurement and an information matrix in GTSAM order.
pub fn format_edge(i: u64, j: u64, z: &Isometry3<f64>, information: &Matrix6<f64>) -> String {
    let t = z.translation.vector;
    let (r, p, y) = se3::rpy_from_rotation(&z.rotation);
    let m = permute_information(information, true);
    let mut line = format!("EDGE3 {i} {j} {} {} {} {r} {p} {y}", t.x, t.y, t.z);
    for a in 0..6 {
        for b in a..6 {
            line.push_str(&format!(" {}", m[(a, b)]));
        }
    }
    line
}

fn pose_from_xyzrpy(v: &[f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        se3::rotation_from_rpy(v[3], v[4], v[5]),
    )
}

/// TORO order → GTSAM order, or back when `to_toro`.
fn permute_information(m: &Matrix6<f64>, to_toro: bool) -> Matrix6<f64> {
    let mut out = Matrix6::zeros();
    for a in 0..6 {
        for b in 0..6 {
            let (sa, sb) = (TORO_OF_GTSAM[a], TORO_OF_GTSAM[b]);
            if to_toro {
                out[(sa, sb)] = m[(a, b)];
            } else {
                out[(a, b)] = m[(sa, sb)];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_information_is_reordered_rotation_first() {
        let line = "0 1 1 2 3 0.1 0.2 0.3 10 0 0 0 0 0 11 0 0 0 0 12 0 0 0 100 0 0 101 0 25";
        let (i, j, z, info) = parse_edge(&mut Tokens::new(line)).unwrap();
        assert_eq!((i, j), (0, 1));
        assert_eq!(z.translation.vector, nalgebra::Vector3::new(1.0, 2.0, 3.0));
        let d = info.diagonal();
        assert_eq!(d.as_slice(), &[100.0, 101.0, 25.0, 10.0, 11.0, 12.0]);
    }

    #[test]
    fn edge_round_trips_through_text() {
        let line = "3 4 1.5 -2 3 0.1 -0.2 0.3 10 1 0 0 0 2 11 0 0 0 0 12 0 0 0 100 0 0 101 3 25";
        let (i, j, z, info) = parse_edge(&mut Tokens::new(line)).unwrap();
        let text = format_edge(i, j, &z, &info);
        let rest = text.strip_prefix("EDGE3 ").unwrap();
        let (i2, j2, z2, info2) = parse_edge(&mut Tokens::new(rest)).unwrap();
        assert_eq!((i, j), (i2, j2));
        assert!((z.to_homogeneous() - z2.to_homogeneous()).abs().max() < 1e-15);
        assert_eq!(info, info2);
    }
}
