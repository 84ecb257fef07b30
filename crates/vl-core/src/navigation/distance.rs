//! The exact Euclidean distance transform of an occupancy grid
//! (Felzenszwalb and Huttenlocher): how far every cell is from the nearest
//! blocked one, what growing obstacles by a disc and the clearance of a
//! path are read from.

use super::grid::Grid;

impl Grid {
    /// Squared distance, in cells², from each cell's centre to the nearest
    /// blocked cell's centre: the exact Euclidean distance transform of
    /// Felzenszwalb and Huttenlocher. [`FAR`] where there is none (within
    /// 65,534 rows: the first pass counts in 16 bits). See
    /// [`Self::distance_transform_within`].
    pub fn distance_transform(&self) -> Vec<u32> {
        self.distance_transform_within(FAR - 1)
    }

    /// The distance transform, exact wherever it is at most `limit` cells²
    /// and [`FAR`] wherever it is more: a C-space only asks "nearer than
    /// this?", and a cell farther from every obstacle than the limit along
    /// its column cannot be anyone's nearest, so the second pass skips it.
    pub(crate) fn distance_transform_within(&self, limit: u32) -> Vec<u32> {
        let mut d = vec![FAR; self.blocked.len()];
        self.transform_rows(limit, &mut d, |row, out| out.copy_from_slice(row));
        d
    }

    /// The cells whose centres are within `limit` cells² of a blocked cell's
    /// centre (the blocked ones among them), without holding the whole
    /// transform.
    pub(super) fn within(&self, limit: u32) -> Vec<bool> {
        let mut near = vec![false; self.blocked.len()];
        self.transform_rows(limit, &mut near, |row, out| {
            for (o, &d) in out.iter_mut().zip(row) {
                *o = d != FAR;
            }
        });
        near
    }

    /// Takes the transform within `limit` row by row, handing `write` each
    /// row's squared distances with that row of `out`.
    ///
    /// The first pass (along columns) is, for a binary map, the distance to
    /// the nearest blocked cell in the column, taken by two sweeps over whole
    /// rows so memory is read in order, and held in 16 bits; the second (the
    /// lower envelope of parabolas along each row, or a sliding minimum for
    /// a small limit) splits its rows between two threads on a large map.
    /// Cells off the map are not counted here; see [`Grid::border_cells`].
    fn transform_rows<T: Send>(
        &self,
        limit: u32,
        out: &mut [T],
        write: impl Fn(&[u32], &mut [T]) + Sync,
    ) {
        let (w, h) = (self.width as usize, self.height as usize);
        // Rows to the nearest blocked cell up or down the column, saturating
        // at NONE: "none within reach". Written without branches (a mask for
        // "blocked") so the sweeps vectorise.
        const NONE: u16 = u16::MAX;
        let mut column = vec![NONE; w * h];
        let free = |b: bool| u16::from(b).wrapping_sub(1);
        for (g, &b) in column.iter_mut().zip(&self.blocked).take(w) {
            *g = NONE & free(b);
        }
        for y in 1..h {
            let (done, row) = column.split_at_mut(y * w);
            let above = &done[(y - 1) * w..];
            let blocked = &self.blocked[y * w..(y + 1) * w];
            for ((g, &a), &b) in row[..w].iter_mut().zip(above).zip(blocked) {
                *g = a.saturating_add(1) & free(b);
            }
        }
        for y in (0..h.saturating_sub(1)).rev() {
            let (row, below) = column[y * w..(y + 2) * w].split_at_mut(w);
            for (g, &b) in row.iter_mut().zip(below.iter()) {
                *g = (*g).min(b.saturating_add(1));
            }
        }
        let reach = limit.isqrt();
        let rows = |column: &[u16], out: &mut [T]| {
            let mut scratch = Scratch::new(w);
            let mut row = vec![0u32; w];
            for (g, out) in column.chunks_exact(w).zip(out.chunks_exact_mut(w)) {
                for (r, &g) in row.iter_mut().zip(g) {
                    *r = if g == NONE { NONE_U32 } else { u32::from(g) };
                }
                if reach <= WINDOW_REACH {
                    scratch.window(&mut row, limit);
                } else {
                    scratch.lower_envelope(&mut row, limit);
                }
                write(&row, out);
            }
        };
        if w * h >= PARALLEL_CELLS && h >= 2 {
            let half = h / 2 * w;
            let (top, bottom) = column.split_at(half);
            let (out_top, out_bottom) = out.split_at_mut(half);
            std::thread::scope(|scope| {
                scope.spawn(|| rows(top, out_top));
                rows(bottom, out_bottom);
            });
        } else {
            rows(&column, out);
        }
    }
}

/// The distance transform's value for "no blocked cell within the limit".
pub const FAR: u32 = u32::MAX;

/// A row's column distance where the column has no blocked cell within reach.
const NONE_U32: u32 = u32::MAX;

/// Maps at least this large share the distance transform's rows between two
/// threads: below it, starting a thread costs more than it saves.
const PARALLEL_CELLS: usize = 1 << 16;

/// Limits up to this many cells out are taken along a row by a sliding
/// minimum over the window, cheaper there than the lower envelope.
const WINDOW_REACH: u32 = 8;

/// Buffers for the 1-D squared distance transform along a row.
struct Scratch {
    /// Columns of the parabolas that may be nearest (within the limit).
    at: Vec<usize>,
    /// Their heights: the squared column distance there.
    f: Vec<f64>,
    /// Columns of the parabolas in the lower envelope.
    v: Vec<usize>,
    /// Where each envelope parabola starts to be the lowest.
    z: Vec<f64>,
    /// The window's squared column distances, capped just past the limit.
    g2: Vec<u32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            at: Vec::with_capacity(n),
            f: Vec::with_capacity(n),
            v: vec![0; n],
            z: vec![0.0; n + 1],
            g2: vec![0; n],
        }
    }

    /// Replaces `row`'s column distances ([`NONE_U32`] for "no blocked
    /// cell within reach") by squared distances within `limit` and [`FAR`] beyond it:
    /// the lower envelope of parabolas of Felzenszwalb and Huttenlocher,
    /// over only the columns near enough to count.
    fn lower_envelope(&mut self, row: &mut [u32], limit: u32) {
        self.at.clear();
        self.f.clear();
        for (x, &g) in row.iter().enumerate() {
            if g != NONE_U32 && u64::from(g) * u64::from(g) <= u64::from(limit) {
                self.at.push(x);
                self.f.push(f64::from(g) * f64::from(g));
            }
        }
        if self.at.is_empty() {
            row.fill(FAR);
            return;
        }
        let (at, f, v, z) = (&self.at, &self.f, &mut self.v, &mut self.z);
        let mut k = 0usize;
        v[0] = 0;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        let sq = |i: usize| (at[i] * at[i]) as f64;
        for q in 1..at.len() {
            loop {
                let p = v[k];
                let s = ((f[q] + sq(q)) - (f[p] + sq(p))) / (2.0 * (at[q] - at[p]) as f64);
                if s <= z[k] && k > 0 {
                    k -= 1;
                } else {
                    k += 1;
                    v[k] = q;
                    z[k] = s;
                    z[k + 1] = f64::INFINITY;
                    break;
                }
            }
        }
        k = 0;
        let limit = f64::from(limit);
        for (x, out) in row.iter_mut().enumerate() {
            while z[k + 1] < x as f64 {
                k += 1;
            }
            let dx = x as f64 - at[v[k]] as f64;
            let d2 = dx * dx + f[v[k]];
            *out = if d2 <= limit { d2 as u32 } else { FAR };
        }
    }

    /// The same as [`Self::lower_envelope`] for a small `limit`: each cell
    /// takes the least dx² + g² over the columns within its square root.
    fn window(&mut self, row: &mut [u32], limit: u32) {
        let reach = limit.isqrt() as usize;
        let beyond = limit + 1;
        let g2 = &mut self.g2[..row.len()];
        for (h, &g) in g2.iter_mut().zip(row.iter()) {
            *h = if (g as usize) <= reach { g * g } else { beyond };
        }
        row.copy_from_slice(g2);
        for dx in 1..reach.min(row.len().saturating_sub(1)) + 1 {
            let d = (dx * dx) as u32;
            let n = row.len() - dx;
            for (out, &h) in row[..n].iter_mut().zip(&g2[dx..]) {
                *out = (*out).min(h + d);
            }
            for (out, &h) in row[dx..].iter_mut().zip(&g2[..n]) {
                *out = (*out).min(h + d);
            }
        }
        for out in row.iter_mut() {
            if *out > limit {
                *out = FAR;
            }
        }
    }
}
