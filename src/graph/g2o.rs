//! g2o 3D lines: `VERTEX_SE3:QUAT id x y z qx qy qz qw` and
//! `EDGE_SE3:QUAT i j x y z qx qy qz qw I11 … I66`, plus `FIX id`.
//!
//! The 21 information entries are the upper triangle, row by row, in g2o's order
//! **(translation, rotation)**; they are swapped to the graph's (rotation, translation)
//! order without rescaling, as GTSAM's `readG2o` does, so that costs match GTSAM's.

use super::file::{parse_fields, LineError, Tokens};
use nalgebra::{Isometry3, Matrix6, Quaternion, Translation3, UnitQuaternion};

/// Parses the fields after `VERTEX_SE3:QUAT`.
pub fn parse_vertex(tokens: &mut Tokens<'_>) -> Result<(u64, Isometry3<f64>), LineError> {
    let id = tokens.id("vertex id")?;
    let v: [f64; 7] = parse_fields(tokens, "VERTEX_SE3:QUAT")?;
    tokens.finish("VERTEX_SE3:QUAT")?;
    Ok((id, pose_from_fields(&v)?))
}

/// Parses the fields after `EDGE_SE3:QUAT`: ids, measurement, information in GTSAM order.
pub fn parse_edge(
    tokens: &mut Tokens<'_>,
) -> Result<(u64, u64, Isometry3<f64>, Matrix6<f64>), LineError> {
    let i = tokens.id("first vertex id")?;
    let j = tokens.id("second vertex id")?;
    let v: [f64; 7] = parse_fields(tokens, "EDGE_SE3:QUAT")?;
    let upper: [f64; 21] = parse_fields(tokens, "EDGE_SE3:QUAT information")?;
    tokens.finish("EDGE_SE3:QUAT")?;
    Ok((
        i,
        j,
        pose_from_fields(&v)?,
        swap_blocks(&segloc_maps::landmark::from_upper_triangle6(&upper)),
    ))
}

/// Formats a `VERTEX_SE3:QUAT` line.
pub fn format_vertex(id: u64, pose: &Isometry3<f64>) -> String {
    format!("VERTEX_SE3:QUAT {id} {}", pose_fields(pose))
}

/// Formats an `EDGE_SE3:QUAT` line from an information matrix in GTSAM order.
pub fn format_edge(i: u64, j: u64, z: &Isometry3<f64>, information: &Matrix6<f64>) -> String {
    let m = swap_blocks(information);
    let mut line = format!("EDGE_SE3:QUAT {i} {j} {}", pose_fields(z));
    for a in 0..6 {
        for b in a..6 {
            line.push_str(&format!(" {}", m[(a, b)]));
        }
    }
    line
}

fn pose_fields(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    format!("{} {} {} {} {} {} {}", t.x, t.y, t.z, q.i, q.j, q.k, q.w)
}

fn pose_from_fields(v: &[f64; 7]) -> Result<Isometry3<f64>, LineError> {
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let n = q.norm();
    if n.is_nan() || n <= 1e-9 {
        return Err(LineError::NotAPose("quaternion has zero norm"));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Swaps the translation and rotation blocks (its own inverse).
fn swap_blocks(m: &Matrix6<f64>) -> Matrix6<f64> {
    let mut out = Matrix6::zeros();
    for a in 0..6 {
        for b in 0..6 {
            out[((a + 3) % 6, (b + 3) % 6)] = m[(a, b)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_round_trips_through_text() {
        let line = "0 1 1 2 3 0.1 0.2 0.3 0.927 10 1 0 0 0 2 11 0 0 0 0 12 0 0 0 100 0 0 101 3 25";
        let (i, j, z, info) = parse_edge(&mut Tokens::new(line)).unwrap();
        assert_eq!(info[(0, 0)], 100.0);
        assert_eq!(info[(3, 3)], 10.0);
        assert_eq!(info[(2, 3)], 2.0); // g2o (x, qz) moves to (rotation z, translation x)
        let text = format_edge(i, j, &z, &info);
        let rest = text.strip_prefix("EDGE_SE3:QUAT ").unwrap();
        let (_, _, z2, info2) = parse_edge(&mut Tokens::new(rest)).unwrap();
        assert!((z.to_homogeneous() - z2.to_homogeneous()).abs().max() < 1e-15);
        assert_eq!(info, info2);
    }

    #[test]
    fn zero_quaternion_is_refused() {
        let e = parse_vertex(&mut Tokens::new("0 1 2 3 0 0 0 0"));
        assert!(e.unwrap_err().to_string().contains("quaternion"));
    }
}
