//! The Khepera's infrared proximity response, and its inverse: the
//! simulator turns distances into readings by it, the Host's safety layer
//! turns readings back into distances.

use crate::{Arena, Pose, SensorMount};

/// What the sensor at `mount` on a robot at `pose` reads of `arena`, noise
/// aside — the IR response to the first surface its ray meets, scaled by
/// how well that surface reflects — and how far that surface is, mm. The
/// simulator adds the sensor's noise to it; the pose estimate compares
/// real readings with it.
pub fn mapped_reading(arena: &Arena, pose: Pose, mount: &SensorMount) -> (f64, f64) {
    let hit = arena.ray_hit(
        pose.to_world(mount.x_mm, mount.y_mm),
        pose.theta_rad + mount.angle_rad,
    );
    (
        hit.reflectivity * ir_reading(hit.distance_mm),
        hit.distance_mm,
    )
}

/// The highest reading: an obstacle touching the sensor.
pub const MAX_READING: f64 = 1023.0;

/// Reading (0–1023, higher = nearer) of a sensor `distance_mm` from a white
/// obstacle: the closed form 52 + 108929 / (d + 5)^1.75, within ~5 % of
/// K-Team's calibration table over its 8–100 mm range.
pub fn ir_reading(distance_mm: f64) -> f64 {
    (52.0 + 108_929.0 / (distance_mm.max(0.0) + 5.0).powf(1.75)).clamp(0.0, MAX_READING)
}

/// How far a white obstacle is that reads `reading`, mm: the inverse of
/// [`ir_reading`]; `None` for a reading too low to come from any distance
/// (the noise floor), and 0 for a saturated reading. A darker obstacle reads lower, so it is nearer than
/// this says: the Host does not rely on the sensors alone.
pub fn ir_distance(reading: f64) -> Option<f64> {
    if reading >= MAX_READING {
        // Saturated: anywhere from touching to about 10 mm.
        return Some(0.0);
    }
    let excess = reading - 52.0;
    (excess > 0.0).then(|| ((108_929.0 / excess).powf(1.0 / 1.75) - 5.0).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn matches_the_calibration_table() {
        let table = [
            (10.0, 1000.0),
            (20.0, 450.0),
            (30.0, 275.0),
            (40.0, 190.0),
            (50.0, 150.0),
            (60.0, 125.0),
            (70.0, 110.0),
            (80.0, 100.0),
            (90.0, 90.0),
            (100.0, 80.0),
        ];
        for (d, v) in table {
            let got = ir_reading(d);
            assert!((got - v).abs() / v < 0.08, "at {d} mm: {got} vs {v}");
        }
        assert_eq!(ir_reading(0.0), 1023.0);
        assert_eq!(ir_distance(10.0), None);
        assert_eq!(ir_distance(f64::NAN), None);
        assert_eq!(ir_distance(1023.0), Some(0.0));
    }

    proptest! {
        /// Reading and distance invert each other over the sensor's range.
        #[test]
        fn the_inverse_inverts(d in 10.0f64..500.0) {
            let back = ir_distance(ir_reading(d)).unwrap();
            prop_assert!((back - d).abs() < 1e-6 * (1.0 + d), "{} → {}", d, back);
        }
    }
}
