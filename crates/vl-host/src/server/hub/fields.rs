//! What the hub has made of the lab's map: its C-space and potential
//! field, made once, and the fields of definitions with virtual obstacles,
//! made off the hub one at a time.

use std::sync::Arc;

use tokio::sync::mpsc;
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

/// Builds a definition's potential field on a blocking thread, one at a
/// time: a definition given while one is built waits in place of any
/// before it, so however many a client sends, the hub never waits and at
/// most one thread works.
pub(super) struct FieldWorker {
    /// The number of the newest definition asked for.
    asked: u64,
    /// Whether a build is under way, and the newest waiting for it.
    busy: bool,
    waiting: Option<(u64, Vec<Shape>)>,
    done_tx: mpsc::UnboundedSender<(u64, Option<MapField>)>,
    pub(super) done: mpsc::UnboundedReceiver<(u64, Option<MapField>)>,
}

impl FieldWorker {
    pub(super) fn new() -> FieldWorker {
        let (done_tx, done) = mpsc::unbounded_channel();
        FieldWorker {
            asked: 0,
            busy: false,
            waiting: None,
            done_tx,
            done,
        }
    }

    /// Asks for the field of `virtual_obstacles` on `lab`'s map; what was
    /// asked before is forgotten.
    pub(super) fn ask(&mut self, lab: &Lab, virtual_obstacles: Vec<Shape>) {
        self.asked += 1;
        self.waiting = Some((self.asked, virtual_obstacles));
        self.next(lab);
    }

    /// Starts the waiting build if none is under way.
    fn next(&mut self, lab: &Lab) {
        if self.busy {
            return;
        }
        let Some((number, shapes)) = self.waiting.take() else {
            return;
        };
        self.busy = true;
        let (arena, radius) = (lab.info.arena.clone(), lab.info.robot.radius_mm);
        let done = self.done_tx.clone();
        tokio::task::spawn_blocking(move || {
            let field = disc_cspace(&arena, &shapes, radius)
                .inspect_err(|e| warn!("no C-space for the definition: {e}"))
                .ok()
                .as_ref()
                .map(map_field);
            let _ = done.send((number, field));
        });
    }

    /// A build ended: its field if it is the newest asked for.
    pub(super) fn finished(
        &mut self,
        lab: &Lab,
        number: u64,
        field: Option<MapField>,
    ) -> Option<Option<MapField>> {
        self.busy = false;
        self.next(lab);
        (number == self.asked).then_some(field)
    }

    /// Whatever is under way or waiting is no longer wanted.
    pub(super) fn forget(&mut self) {
        self.asked += 1;
        self.waiting = None;
    }
}
