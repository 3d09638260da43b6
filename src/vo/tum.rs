//! TUM trajectories: `t tx ty tz qx qy qz qw` per line.

use nalgebra::Isometry3;

/// The text of a TUM trajectory.
pub fn tum_text(poses: &[(f64, Isometry3<f64>)]) -> String {
    let mut out = String::new();
    for (t, p) in poses {
        let (v, q) = (p.translation.vector, p.rotation.coords);
        out += &format!(
            "{t:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}\n",
            v.x, v.y, v.z, q.x, q.y, q.z, q.w
        );
    }
    out
}
