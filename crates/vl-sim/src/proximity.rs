//! The Khepera's infrared proximity response.

/// Reading (0–1023, higher = nearer) of a sensor `distance_mm` from a white
/// obstacle: the closed form 52 + 108929 / (d + 5)^1.75, within ~5 % of
/// K-Team's calibration table over its 8–100 mm range.
pub(crate) fn proximity_value(distance_mm: f64) -> f64 {
    (52.0 + 108_929.0 / (distance_mm.max(0.0) + 5.0).powf(1.75)).clamp(0.0, 1023.0)
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let got = proximity_value(d);
            assert!((got - v).abs() / v < 0.08, "at {d} mm: {got} vs {v}");
        }
        assert_eq!(proximity_value(0.0), 1023.0);
    }
}
