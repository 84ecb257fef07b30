//! The NF1 navigation function: a wavefront from the goal over the free
//! cells of the C-space, each cell's value the number of grid steps to the
//! goal; and the descent that follows it from the start.
//!
//! Steps move to an edge neighbour (4-connected), or also to a corner
//! neighbour when both cells beside the diagonal are free (8-connected: the
//! robot never squeezes between two obstacle corners). With several θ
//! slices, turning to the next slice in the same cell is a step too.

use crate::{CSpace, Connectivity};

/// A cell of the C-space: column, row, θ slice.
pub type CSpaceCell = (u32, u32, u32);

/// Value of a cell the wavefront never reached.
const UNREACHED: u32 = u32::MAX;
/// Value of a blocked cell, and of the ring of cells around each slice
/// that stands for "off the map" (so steps need no bounds checks).
const BLOCKED: u32 = u32::MAX - 1;

/// NF1 values over every cell of every slice.
#[derive(Debug, Clone)]
pub struct Nf1 {
    width: u32,
    height: u32,
    slices: u32,
    connectivity: Connectivity,
    /// Per slice, row-major with a one-cell border; slice after slice.
    values: Vec<u32>,
}

impl Nf1 {
    /// Breadth-first wavefront from `goal` over every cell it reaches. A
    /// goal in an obstacle reaches nothing.
    pub fn from_goal(cspace: &CSpace, goal: CSpaceCell, connectivity: Connectivity) -> Nf1 {
        Nf1::wave(cspace, goal, connectivity, None)
    }

    /// The wavefront from `goal` only as far as `start`: it stops with the
    /// wave that reaches the start, which fixes every value the descent from
    /// there reads (all lower); cells farther out are left unreached. A
    /// start near the goal costs a small ball, not the whole map.
    pub fn toward(
        cspace: &CSpace,
        goal: CSpaceCell,
        start: CSpaceCell,
        connectivity: Connectivity,
    ) -> Nf1 {
        Nf1::wave(cspace, goal, connectivity, Some(start))
    }

    fn wave(
        cspace: &CSpace,
        goal: CSpaceCell,
        connectivity: Connectivity,
        until: Option<CSpaceCell>,
    ) -> Nf1 {
        let grid = cspace.grid();
        let (width, height) = (grid.width, grid.height);
        let mut nf1 = Nf1 {
            width,
            height,
            slices: cspace.slices.len() as u32,
            connectivity,
            values: Vec::new(),
        };
        let stride = nf1.stride();
        nf1.values = vec![BLOCKED; nf1.plane() * cspace.slices.len()];
        for (k, slice) in cspace.slices.iter().enumerate() {
            for (r, row) in slice.blocked.chunks_exact(width as usize).enumerate() {
                let base = k * nf1.plane() + (r + 1) * stride + 1;
                for (v, &b) in nf1.values[base..base + width as usize].iter_mut().zip(row) {
                    *v = if b { BLOCKED } else { UNREACHED };
                }
            }
        }
        let start = nf1.index(goal);
        if nf1.values[start] == BLOCKED {
            return nf1;
        }
        nf1.values[start] = 0;
        // Wave by wave: only the front is held (a few thousand cells on a
        // map of a million), so a big map costs no queue as large as itself.
        let mut front: Vec<u32> = vec![start as u32];
        let mut next_front: Vec<u32> = Vec::new();
        let s = stride;
        let eight = connectivity == Connectivity::Eight && nf1.slices == 1;
        let until = until.map(|cell| nf1.index(cell));
        let mut next = 0u32;
        while !front.is_empty() && until.is_none_or(|i| nf1.values[i] == UNREACHED) {
            next += 1;
            for &i in &front {
                let i = i as usize;
                if nf1.slices > 1 {
                    let (steps, n) = nf1.steps(i);
                    for &j in &steps[..n] {
                        if nf1.values[j] == UNREACHED {
                            nf1.values[j] = next;
                            next_front.push(j as u32);
                        }
                    }
                    continue;
                }
                // One slice: the rule of `steps` written out, which makes the
                // wave three times faster (the descent, through `steps`, and
                // the property tests check the two agree).
                let v = &mut nf1.values;
                let (right, left, down, up) = (i + 1, i - 1, i + s, i - s);
                for j in [right, left, down, up] {
                    if v[j] == UNREACHED {
                        v[j] = next;
                        next_front.push(j as u32);
                    }
                }
                if eight {
                    for (side, vertical) in [(right, down), (right, up), (left, down), (left, up)] {
                        let corner = side + vertical - i;
                        if v[corner] == UNREACHED && v[side] != BLOCKED && v[vertical] != BLOCKED {
                            v[corner] = next;
                            next_front.push(corner as u32);
                        }
                    }
                }
            }
            std::mem::swap(&mut front, &mut next_front);
            next_front.clear();
        }
        nf1
    }

    /// The free cells one step from cell `i`, and how many there are.
    #[inline(always)]
    fn steps(&self, i: usize) -> ([usize; 10], usize) {
        let v = &self.values;
        let s = self.stride();
        let mut out = [0; 10];
        let mut n = 0;
        let mut push = |j: usize| {
            out[n] = j;
            n += 1;
        };
        // The border ring is BLOCKED, so i ± 1 and i ± stride stay in bounds.
        let (right, left, down, up) = (i + 1, i - 1, i + s, i - s);
        for j in [right, left, down, up] {
            if v[j] != BLOCKED {
                push(j);
            }
        }
        if self.connectivity == Connectivity::Eight {
            for (side, vertical) in [(right, down), (right, up), (left, down), (left, up)] {
                let corner = side + vertical - i;
                if v[side] != BLOCKED && v[vertical] != BLOCKED && v[corner] != BLOCKED {
                    push(corner);
                }
            }
        }
        if self.slices > 1 {
            let plane = self.plane();
            let (k, base) = (i / plane, i % plane);
            let m = self.slices as usize;
            // With two slices, turning either way reaches the same one.
            let turns = if m == 2 { 1 } else { 2 };
            for kk in [(k + 1) % m, (k + m - 1) % m].into_iter().take(turns) {
                let j = kk * plane + base;
                if v[j] != BLOCKED {
                    push(j);
                }
            }
        }
        (out, n)
    }

    /// The number of steps from `cell` to the goal, or None when it cannot
    /// reach the goal (or is blocked).
    pub fn value(&self, cell: CSpaceCell) -> Option<u32> {
        let v = self.values[self.index(cell)];
        (v < BLOCKED).then_some(v)
    }

    /// The path of steepest descent from `start` to the goal: each step goes
    /// to a neighbour one value lower, preferring the one nearest the goal
    /// in the plane so the staircase hugs the straight line. None when the
    /// start cannot reach the goal.
    pub fn descend(&self, start: CSpaceCell, goal: CSpaceCell) -> Option<Vec<CSpaceCell>> {
        let mut value = self.value(start)?;
        let mut path = Vec::with_capacity(value as usize + 1);
        let mut i = self.index(start);
        path.push(start);
        let to_goal = |j: usize| {
            let (c, r, _) = self.cell(j);
            let (dc, dr) = (
                f64::from(c) - f64::from(goal.0),
                f64::from(r) - f64::from(goal.1),
            );
            dc * dc + dr * dr
        };
        while value > 0 {
            let (steps, n) = self.steps(i);
            i = steps[..n]
                .iter()
                .copied()
                .filter(|&j| self.values[j] == value - 1)
                .min_by(|&a, &b| to_goal(a).total_cmp(&to_goal(b)).then(a.cmp(&b)))
                .expect("a reached cell has a neighbour one step nearer the goal");
            value -= 1;
            path.push(self.cell(i));
        }
        Some(path)
    }

    fn stride(&self) -> usize {
        self.width as usize + 2
    }

    fn plane(&self) -> usize {
        self.stride() * (self.height as usize + 2)
    }

    fn index(&self, (c, r, k): CSpaceCell) -> usize {
        k as usize * self.plane() + (r as usize + 1) * self.stride() + c as usize + 1
    }

    fn cell(&self, i: usize) -> CSpaceCell {
        let (k, rest) = (i / self.plane(), i % self.plane());
        let (r, c) = (rest / self.stride(), rest % self.stride());
        ((c - 1) as u32, (r - 1) as u32, k as u32)
    }
}
