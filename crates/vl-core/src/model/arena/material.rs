//! What obstacles are made of, as the infrared sensors and the camera see it.

use serde::{Deserialize, Serialize};

use crate::Shape;

/// What an obstacle's surface is like to the robot's infrared sensors and
/// to the overhead camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Material {
    /// Fraction of the infrared a white surface returns (K-Team's
    /// calibration is for white): 0.01 for matt black, 1 for white.
    #[serde(default = "Material::white_ir")]
    pub reflectivity: f64,
    /// sRGB colour the camera sees from above.
    #[serde(default = "Material::dark")]
    pub colour: [u8; 3],
}

impl Material {
    fn white_ir() -> f64 {
        1.0
    }

    fn dark() -> [u8; 3] {
        [48, 50, 58]
    }

    pub(crate) fn check(&self) -> Result<(), String> {
        if self.reflectivity.is_finite() && (0.0..=1.0).contains(&self.reflectivity) {
            Ok(())
        } else {
            Err(format!(
                "its reflectivity must be between 0 and 1, not {}",
                self.reflectivity
            ))
        }
    }
}

impl Default for Material {
    /// Dark tops with white sides: how the lab's wooden blocks look.
    fn default() -> Self {
        Material {
            reflectivity: Material::white_ir(),
            colour: Material::dark(),
        }
    }
}

/// An obstacle: a shape and what it is made of.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Obstacle {
    #[serde(flatten)]
    pub shape: Shape,
    #[serde(flatten)]
    pub material: Material,
}

impl From<Shape> for Obstacle {
    fn from(shape: Shape) -> Self {
        Obstacle {
            shape,
            material: Material::default(),
        }
    }
}
