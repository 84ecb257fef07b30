//! The mobile-robotics lab's navigation (thesis appendix B): the C-space
//! of a map grown by the robot's footprint, the NF1 navigation function and
//! its descent, a cubic spline through it, and following the smooth path.

pub(crate) mod analysis;
pub(crate) mod bench;
pub(crate) mod cspace;
pub(crate) mod distance;
pub(crate) mod follow;
pub(crate) mod grid;
pub(crate) mod localise;
pub(crate) mod nf1;
pub(crate) mod plan;
pub(crate) mod report;
pub(crate) mod spline;
pub(crate) mod svg;
