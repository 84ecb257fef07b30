//! What the hub has made of the lab's map: its C-space and potential
//! field, made once, and the fields of definitions with virtual obstacles,
//! made off the hub.

use std::sync::Arc;

use tracing::warn;
use vl_core::{CSpace, MapField, Shape, disc_cspace};

use crate::lab::{Lab, map_field};

/// What the lab's map always gives: its C-space and (for teleoperation)
/// its potential field.
pub(super) struct Map {
    pub(super) cspace: Option<Arc<CSpace>>,
    pub(super) field: Option<Arc<MapField>>,
}

impl Map {
    pub(super) fn new(lab: &Lab) -> Map {
        let info = &lab.info;
        let cspace = disc_cspace(&info.arena, &[], info.robot.radius_mm)
            .inspect_err(|e| warn!("no C-space for the lab's map: {e}"))
            .ok()
            .map(Arc::new);
        let field = cspace.as_deref().map(map_field).map(Arc::new);
        Map { cspace, field }
    }
}

/// The field of `virtual_obstacles` on `lab`'s map, made off the hub
/// (by a [`JobThread`](super::worker::JobThread)); none if the C-space cannot be made.
pub(super) fn field_job(
    lab: &Lab,
    virtual_obstacles: Vec<Shape>,
) -> impl FnOnce(&std::sync::atomic::AtomicBool) -> Option<MapField> + Send + 'static {
    let (arena, radius) = (lab.info.arena.clone(), lab.info.robot.radius_mm);
    move |_| {
        disc_cspace(&arena, &virtual_obstacles, radius)
            .inspect_err(|e| warn!("no C-space for the definition: {e}"))
            .ok()
            .as_ref()
            .map(map_field)
    }
}
