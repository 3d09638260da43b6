//! IPEX rover and camera geometry: the rover's drive limits and wheel layout, the stereo
//! cameras, the lander's size and the site's bounds.
//!
//! A leaf module (it imports nothing) because several layers describe the same vehicle:
//! the stereo noise model of the landmarks ([`crate::landmarks::stereo_noise`]), the
//! planner's drive limits and lander box ([`crate::planning`]) and the simulator
//! ([`crate::sim`], which re-exports this module as `sim::ipex`).
//!
//! The numbers come from `lac-images/ipex_geometry.json` and `README.md` in the shared data
//! folder (`$SEGLOC_DATA`), the Lunar Autonomy Challenge's description of the IPEX rover:
//! rover body frame x forward, y left, z up, origin at the IMU.

/// Simulator control rate, Hz.
pub const TICK_HZ: f64 = 20.0;
/// Simulator control period, seconds.
pub const TICK_S: f64 = 1.0 / TICK_HZ;
/// Maximum linear speed, m/s (LAC rover limit).
pub const MAX_SPEED_MPS: f64 = 0.49;
/// Maximum yaw rate, rad/s (LAC rover limit).
pub const MAX_YAW_RATE_RPS: f64 = 4.13;
/// The rover must stay within |x|, |y| ≤ this, metres (LAC rule).
pub const SITE_HALF_EXTENT_M: f64 = 19.5;
/// Lunar gravity, m/s².
pub const LUNAR_GRAVITY_MPS2: f64 = 1.622;

/// Wheel centre, forward offset from the body origin (ipex_geometry.json "wheels": ±0.222).
pub const WHEEL_X_M: f64 = 0.222;
/// Wheel centre, lateral offset (ipex_geometry.json "wheels": ±0.203).
pub const WHEEL_Y_M: f64 = 0.203;
/// Wheel centre height above the body origin (ipex_geometry.json "wheels": 0.041).
pub const WHEEL_Z_M: f64 = 0.041;
/// Wheel diameter (ipex_geometry.json "wheels": 0.32).
pub const WHEEL_DIAMETER_M: f64 = 0.32;
/// Wheel width (ipex_geometry.json "wheels": 0.127).
pub const WHEEL_WIDTH_M: f64 = 0.127;
/// Height of the body origin above the ground under the wheels: wheel radius minus the
/// wheel centre's height (0.16 − 0.041 = 0.119 m; the README notes the rover's z is about
/// 0.11 m above the LAC cell height).
pub const BODY_ABOVE_GROUND_M: f64 = WHEEL_DIAMETER_M / 2.0 - WHEEL_Z_M;
/// Radius of the circle around the body origin that contains the whole rover footprint
/// (wheel outer corner at (0.222 + 0.16, 0.203 + 0.0635)): ≈ 0.466 m.
pub fn footprint_radius_m() -> f64 {
    let x = WHEEL_X_M + WHEEL_DIAMETER_M / 2.0;
    let y = WHEEL_Y_M + WHEEL_WIDTH_M / 2.0;
    x.hypot(y)
}

/// Front-left camera position (ipex_geometry.json "FrontLeft": (0.28, 0.081, 0.131)), looking
/// along +x; the stereo reference camera of the front pair.
pub const FRONT_LEFT_CAMERA_M: [f64; 3] = [0.28, 0.081, 0.131];
/// Back-left camera position (ipex_geometry.json "BackLeft": (−0.28, −0.081, 0.131)), looking
/// along −x (yaw π); the stereo reference camera of the back pair.
pub const BACK_LEFT_CAMERA_M: [f64; 3] = [-0.28, -0.081, 0.131];
/// Stereo baseline, metres (README: front stereo baseline 0.162 m = 2 × 0.081).
pub const STEREO_BASELINE_M: f64 = 0.162;
/// Image width, pixels.
pub const IMAGE_WIDTH_PX: f64 = 1280.0;
/// Image height, pixels.
pub const IMAGE_HEIGHT_PX: f64 = 720.0;
/// Focal length, pixels (README: fx = fy = 914.015, 70° horizontal field of view).
pub const FOCAL_PX: f64 = 914.015;
/// Principal point, column.
pub const CX_PX: f64 = 640.0;
/// Principal point, row.
pub const CY_PX: f64 = 360.0;

/// Lander half-width in x and y, metres: the fiducial groups sit at ±1.033 m
/// (ipex_geometry.json "lander"), so the body is about 3 m × 3 m with its legs.
pub const LANDER_HALF_EXTENT_M: f64 = 1.5;
/// Lander height above the ground, metres (fiducials reach 0.894 + 0.339/2; the body and
/// antenna mast go higher).
pub const LANDER_HEIGHT_M: f64 = 2.5;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_geometry() {
        assert!((BODY_ABOVE_GROUND_M - 0.119).abs() < 1e-12);
        assert!((footprint_radius_m() - 0.4662).abs() < 1e-3);
        // 70° horizontal field of view at fx = 914.015 and 1280 columns.
        let hfov = 2.0 * (CX_PX / FOCAL_PX).atan();
        assert!((hfov.to_degrees() - 70.0).abs() < 0.01);
    }
}
