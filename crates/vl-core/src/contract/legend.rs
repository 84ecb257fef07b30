//! One colour legend for every view of the lab: the desktop window draws
//! with it and the Host serves it to the page (`/legend.js`), so a student
//! moving between the two reads each colour the same way.

/// What a view draws over the camera image or the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// The robot where the last feedback put it.
    Robot,
    /// Where the predictive display puts it now.
    Ghost,
    /// Where it drove in this run.
    Trail,
    /// The path it is to follow (dashed while only planned).
    Path,
    /// The definition's runs on the lab's twin.
    Forecast,
    Goal,
    VirtualObstacle,
    /// The obstacles' push; the robot is outlined in it when held back.
    Force,
    /// The arena drawn from its model, where there is no camera image.
    Floor,
    Obstacle,
}

impl Mark {
    pub const ALL: [Mark; 10] = [
        Mark::Robot,
        Mark::Ghost,
        Mark::Trail,
        Mark::Path,
        Mark::Forecast,
        Mark::Goal,
        Mark::VirtualObstacle,
        Mark::Force,
        Mark::Floor,
        Mark::Obstacle,
    ];

    /// Its colour, red, green, blue.
    pub const fn rgb(self) -> [u8; 3] {
        match self {
            Mark::Robot => [40, 200, 255],
            Mark::Ghost => [235, 90, 255],
            Mark::Trail => [0, 170, 150],
            Mark::Path => [250, 220, 40],
            Mark::Forecast => [150, 150, 255],
            Mark::Goal => [40, 190, 60],
            Mark::VirtualObstacle => [255, 150, 0],
            Mark::Force => [255, 70, 90],
            Mark::Floor => [226, 224, 218],
            Mark::Obstacle => [45, 48, 56],
        }
    }

    /// What it means, as the legend says it.
    pub const fn words(self) -> &'static str {
        match self {
            Mark::Robot => "robot, as last reported",
            Mark::Ghost => "ghost: where it is now, predicted",
            Mark::Trail => "driven",
            Mark::Path => "path (dashed: planned, not yet defined)",
            Mark::Forecast => "forecast",
            Mark::Goal => "goal",
            Mark::VirtualObstacle => "virtual obstacle",
            Mark::Force => "obstacles' push (robot outlined: held back)",
            Mark::Floor => "floor, from the arena's map (no camera image)",
            Mark::Obstacle => "obstacle, from the arena's map",
        }
    }

    /// Its name in the page's script.
    pub const fn id(self) -> &'static str {
        match self {
            Mark::Robot => "robot",
            Mark::Ghost => "ghost",
            Mark::Trail => "trail",
            Mark::Path => "path",
            Mark::Forecast => "forecast",
            Mark::Goal => "goal",
            Mark::VirtualObstacle => "virtual_obstacle",
            Mark::Force => "force",
            Mark::Floor => "floor",
            Mark::Obstacle => "obstacle",
        }
    }

    /// Its colour as CSS writes it.
    pub fn css(self) -> String {
        let [r, g, b] = self.rgb();
        format!("#{r:02x}{g:02x}{b:02x}")
    }
}

#[cfg(test)]
mod tests {
    use super::Mark;

    #[test]
    fn every_mark_has_its_own_colour_and_name() {
        for (i, a) in Mark::ALL.iter().enumerate() {
            for b in &Mark::ALL[i + 1..] {
                assert_ne!(a.rgb(), b.rgb(), "{a:?} and {b:?}");
                assert_ne!(a.id(), b.id());
            }
        }
        assert_eq!(Mark::Robot.css(), "#28c8ff");
    }
}
