//! Connected components of a binary image, labelled over row runs, with
//! their moments in closed form, Hu invariants and enclosed holes.

use serde::Serialize;

use super::Connectivity;
use super::threshold::Mask;

/// One connected component and what its shape says.
#[derive(Debug, Clone, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Component {
    /// Its number in the label image (1, 2, …; 0 is background).
    pub label: u32,
    pub area: u64,
    pub centroid: Centroid,
    /// Left, top, width, height, px.
    pub bbox: [u32; 4],
    /// Angle of the principal axis from +x towards +y (image rows, down), rad.
    pub orientation_rad: f64,
    pub hu: [f64; 7],
    /// Pixels of background it encloses completely.
    pub hole_area: u64,
    /// Centroid of those enclosed pixels, if any.
    #[serde(skip)]
    pub hole_centroid: Option<Centroid>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, schemars::JsonSchema)]
pub struct Centroid {
    pub x: f64,
    pub y: f64,
}
/// Runs of equal pixels along each row: the unit labelling and moments
/// work on, so a long stretch of floor or wall costs one step, not one per
/// pixel.
#[derive(Debug, Clone, Default)]
struct RowRuns {
    /// (first column, end column, row), in raster order.
    spans: Vec<(u32, u32, u32)>,
    /// Index in `spans` of each row's first run, and one past the last row.
    rows: Vec<usize>,
}

impl RowRuns {
    /// The runs of foreground pixels.
    fn of(mask: &Mask) -> RowRuns {
        let w = mask.width as usize;
        let mut runs = RowRuns::default();
        for (r, row) in mask.pixels.chunks_exact(w.max(1)).enumerate() {
            runs.rows.push(runs.spans.len());
            let mut c = 0;
            while c < w {
                if row[c] {
                    let start = c;
                    while c < w && row[c] {
                        c += 1;
                    }
                    runs.spans.push((start as u32, c as u32, r as u32));
                } else {
                    c += 1;
                }
            }
        }
        runs.rows.push(runs.spans.len());
        runs
    }

    /// The runs of everything else in rows `width` wide: the gaps between
    /// these runs and the rows' ends.
    fn gaps(&self, width: u32) -> RowRuns {
        let mut gaps = RowRuns::default();
        for r in 0..self.rows.len().saturating_sub(1) {
            gaps.rows.push(gaps.spans.len());
            let mut from = 0;
            for i in self.row(r) {
                let (a, b, _) = self.spans[i];
                if a > from {
                    gaps.spans.push((from, a, r as u32));
                }
                from = b;
            }
            if from < width {
                gaps.spans.push((from, width, r as u32));
            }
        }
        gaps.rows.push(gaps.spans.len());
        gaps
    }

    /// The runs of row `r`, as a range of indices.
    fn row(&self, r: usize) -> std::ops::Range<usize> {
        self.rows[r]..self.rows[r + 1]
    }

    /// Each run's component number (1.. in raster order of first pixel)
    /// and the number of components: union-find over runs of consecutive
    /// rows that touch (overlap, or meet at a corner under 8-connectivity).
    fn label(&self, connectivity: Connectivity) -> (Vec<u32>, u32) {
        let n = self.spans.len();
        // A root is the smallest run index of its set, so roots come in
        // raster order of their first run.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        let reach = u32::from(connectivity == Connectivity::Eight);
        for r in 1..self.rows.len().saturating_sub(1) {
            let above = self.row(r - 1);
            let mut j = above.start;
            for i in self.row(r) {
                let (a, b, _) = self.spans[i];
                // Skip runs above that end before this one can touch them.
                while j < above.end && self.spans[j].1 + reach <= a {
                    j += 1;
                }
                let mut k = j;
                while k < above.end && self.spans[k].0 < b + reach {
                    let (x, y) = (find(&mut parent, i as u32), find(&mut parent, k as u32));
                    if x != y {
                        let (lo, hi) = (x.min(y), x.max(y));
                        parent[hi as usize] = lo;
                    }
                    k += 1;
                }
            }
        }
        let mut number = vec![0u32; n];
        let mut count = 0;
        for x in 0..n {
            let root = find(&mut parent, x as u32) as usize;
            if root == x {
                count += 1;
                number[x] = count;
            } else {
                number[x] = number[root];
            }
        }
        (number, count)
    }

    /// The label image these runs' numbers paint (0 elsewhere).
    fn paint(&self, number: &[u32], width: u32, height: u32) -> Vec<u32> {
        let w = width as usize;
        let mut labels = vec![0u32; w * height as usize];
        for (&(a, b, r), &l) in self.spans.iter().zip(number) {
            let row = r as usize * w;
            labels[row + a as usize..row + b as usize].fill(l);
        }
        labels
    }
}

/// Labels of each pixel (0 background, components 1.. in raster order of
/// their first pixel) and the number of components.
pub fn label(mask: &Mask, connectivity: Connectivity) -> (Vec<u32>, u32) {
    let runs = RowRuns::of(mask);
    let (number, count) = runs.label(connectivity);
    (runs.paint(&number, mask.width, mask.height), count)
}

/// Raw moment sums of one component, exact in integers (third order in
/// 128 bits: x³ summed over a large component passes 2⁶⁴).
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    m00: u64,
    m10: u64,
    m01: u64,
    m20: u64,
    m11: u64,
    m02: u64,
    m30: u128,
    m21: u128,
    m12: u128,
    m03: u128,
    left: u32,
    top: u32,
    right: u32,
    bottom: u32,
}

/// Σ xᵏ for x in 0..m, k = 1, 2, 3.
fn power_sums(m: u64) -> (u64, u64, u128) {
    let m1 = u128::from(m);
    let s1 = m1 * m1.saturating_sub(1) / 2;
    let s2 = m1.saturating_sub(1) * m1 * (2 * m1).saturating_sub(1) / 6;
    (s1 as u64, s2 as u64, s1 * s1)
}

impl Sums {
    /// Adds the pixels a ≤ x < b of row y.
    fn add_run(&mut self, a: u32, b: u32, y: u32) {
        if self.m00 == 0 {
            (self.left, self.top, self.right, self.bottom) = (a, y, b - 1, y);
        }
        self.left = self.left.min(a);
        self.right = self.right.max(b - 1);
        self.top = self.top.min(y);
        self.bottom = self.bottom.max(y);
        let (pa, pb) = (power_sums(u64::from(a)), power_sums(u64::from(b)));
        let n = u64::from(b - a);
        let (sx, sxx, sxxx) = (pb.0 - pa.0, pb.1 - pa.1, pb.2 - pa.2);
        let y1 = u64::from(y);
        let y3 = u128::from(y);
        self.m00 += n;
        self.m10 += sx;
        self.m01 += n * y1;
        self.m20 += sxx;
        self.m11 += sx * y1;
        self.m02 += n * y1 * y1;
        self.m30 += sxxx;
        self.m21 += u128::from(sxx) * y3;
        self.m12 += u128::from(sx) * y3 * y3;
        self.m03 += u128::from(n) * y3 * y3 * y3;
    }

    /// Adds one pixel: the plain definition, which tests hold runs to.
    #[cfg(test)]
    fn add(&mut self, x: u32, y: u32) {
        if self.m00 == 0 {
            (self.left, self.top, self.right, self.bottom) = (x, y, x, y);
        }
        self.left = self.left.min(x);
        self.right = self.right.max(x);
        self.top = self.top.min(y);
        self.bottom = self.bottom.max(y);
        let (x, y) = (u64::from(x), u64::from(y));
        self.m00 += 1;
        self.m10 += x;
        self.m01 += y;
        self.m20 += x * x;
        self.m11 += x * y;
        self.m02 += y * y;
        let (x3, y3) = (u128::from(x), u128::from(y));
        self.m30 += x3 * x3 * x3;
        self.m21 += x3 * x3 * y3;
        self.m12 += x3 * y3 * y3;
        self.m03 += y3 * y3 * y3;
    }

    /// Adds another region's sums (several holes in one component).
    fn merge(&mut self, add: &Sums) {
        if self.m00 == 0 {
            *self = *add;
            return;
        }
        self.m00 += add.m00;
        self.m10 += add.m10;
        self.m01 += add.m01;
        self.m20 += add.m20;
        self.m11 += add.m11;
        self.m02 += add.m02;
        self.m30 += add.m30;
        self.m21 += add.m21;
        self.m12 += add.m12;
        self.m03 += add.m03;
        self.left = self.left.min(add.left);
        self.top = self.top.min(add.top);
        self.right = self.right.max(add.right);
        self.bottom = self.bottom.max(add.bottom);
    }

    fn centroid(&self) -> Centroid {
        let a = self.m00 as f64;
        Centroid {
            x: self.m10 as f64 / a,
            y: self.m01 as f64 / a,
        }
    }

    /// Principal-axis angle and the seven Hu invariants.
    fn shape(&self) -> (f64, [f64; 7]) {
        let f = |v: u64| v as f64;
        let f3 = |v: u128| v as f64;
        let Centroid { x: cx, y: cy } = self.centroid();
        let mu20 = f(self.m20) - f(self.m10) * cx;
        let mu11 = f(self.m11) - f(self.m10) * cy;
        let mu02 = f(self.m02) - f(self.m01) * cy;
        let mu30 = f3(self.m30) - cx * (3.0 * mu20 + cx * f(self.m10));
        let mu21 = f3(self.m21) - cx * (2.0 * mu11 + cx * f(self.m01)) - cy * mu20;
        let mu12 = f3(self.m12) - cy * (2.0 * mu11 + cy * f(self.m10)) - cx * mu02;
        let mu03 = f3(self.m03) - cy * (3.0 * mu02 + cy * f(self.m01));
        let inv = 1.0 / f(self.m00);
        let (s2, s3) = (inv * inv, inv * inv * inv.sqrt());
        let (n20, n11, n02) = (mu20 * s2, mu11 * s2, mu02 * s2);
        let (n30, n21, n12, n03) = (mu30 * s3, mu21 * s3, mu12 * s3, mu03 * s3);
        let (a, b) = (n30 + n12, n21 + n03);
        let (p, q) = (n30 - 3.0 * n12, 3.0 * n21 - n03);
        let d = n20 - n02;
        let hu = [
            n20 + n02,
            d * d + 4.0 * n11 * n11,
            p * p + q * q,
            a * a + b * b,
            p * a * (a * a - 3.0 * b * b) + q * b * (3.0 * a * a - b * b),
            d * (a * a - b * b) + 4.0 * n11 * a * b,
            q * a * (a * a - 3.0 * b * b) - p * b * (3.0 * a * a - b * b),
        ];
        (0.5 * (2.0 * mu11).atan2(mu20 - mu02), hu)
    }
}

/// The components of `mask` with their statistics, in label order, and the
/// label image. Holes are background regions (of the complementary
/// connectivity) that do not reach the image's border.
pub fn components(mask: &Mask, connectivity: Connectivity) -> (Vec<Component>, Vec<u32>) {
    let runs = RowRuns::of(mask);
    let (number, count) = runs.label(connectivity);
    let labels = runs.paint(&number, mask.width, mask.height);
    let mut sums = vec![Sums::default(); count as usize + 1];
    for (&(a, b, r), &l) in runs.spans.iter().zip(&number) {
        sums[l as usize].add_run(a, b, r);
    }
    let holes = holes(&runs, mask, &labels, count, connectivity);
    let found = (1..=count as usize)
        .map(|l| {
            let s = &sums[l];
            let (orientation_rad, hu) = s.shape();
            let hole = &holes[l];
            Component {
                label: l as u32,
                area: s.m00,
                centroid: s.centroid(),
                bbox: [s.left, s.top, s.right - s.left + 1, s.bottom - s.top + 1],
                orientation_rad,
                hu,
                hole_area: hole.m00,
                hole_centroid: (hole.m00 > 0).then(|| hole.centroid()),
            }
        })
        .collect();
    (found, labels)
}

/// Per component label (of `components` in all), the moment sums of the
/// background it encloses: background regions, of the complementary
/// connectivity, that do not reach the image's border.
fn holes(
    foreground: &RowRuns,
    mask: &Mask,
    labels: &[u32],
    components: u32,
    connectivity: Connectivity,
) -> Vec<Sums> {
    let (w, h) = (mask.width, mask.height);
    let dual = match connectivity {
        Connectivity::Four => Connectivity::Eight,
        Connectivity::Eight => Connectivity::Four,
    };
    let runs = foreground.gaps(w);
    let (region_of, count) = runs.label(dual);
    let count = count as usize;
    let mut enclosing = vec![0u32; count + 1];
    let mut touches_border = vec![false; count + 1];
    let mut sums = vec![Sums::default(); count + 1];
    for (&(a, b, r), &region) in runs.spans.iter().zip(&region_of) {
        let region = region as usize;
        if a == 0 || r == 0 || b == w || r + 1 == h {
            touches_border[region] = true;
        }
        // A region's first run has foreground above its first pixel: the
        // enclosing component.
        if sums[region].m00 == 0 && r > 0 {
            enclosing[region] = labels[(r as usize - 1) * w as usize + a as usize];
        }
        sums[region].add_run(a, b, r);
    }
    let mut per_component = vec![Sums::default(); components as usize + 1];
    for region in 1..=count {
        if !touches_border[region] && enclosing[region] != 0 {
            per_component[enclosing[region] as usize].merge(&sums[region]);
        }
    }
    per_component
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn mask(rows: &[&str]) -> Mask {
        Mask {
            width: rows[0].len() as u32,
            height: rows.len() as u32,
            pixels: rows
                .iter()
                .flat_map(|r| r.chars().map(|c| c == '#'))
                .collect(),
        }
    }

    #[test]
    fn diagonal_neighbours_join_only_under_eight_connectivity() {
        let m = mask(&["#..", ".#.", "..#", "#.."]);
        assert_eq!(label(&m, Connectivity::Eight).1, 2);
        assert_eq!(label(&m, Connectivity::Four).1, 4);
    }

    #[test]
    fn a_ring_has_a_hole_and_its_centre() {
        let m = mask(&["#####", "#...#", "#...#", "#####"]);
        let (found, _) = components(&m, Connectivity::Eight);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].area, 14);
        assert_eq!(found[0].hole_area, 6);
        assert_eq!(found[0].hole_centroid, Some(Centroid { x: 2.0, y: 1.5 }));
        assert_eq!(found[0].bbox, [0, 0, 5, 4]);
    }

    /// A naive flood fill over `mask`.
    fn flood_count(m: &Mask, connectivity: Connectivity) -> u32 {
        let (w, h) = (m.width as i64, m.height as i64);
        let mut seen = vec![false; m.pixels.len()];
        let mut count = 0;
        for start in 0..m.pixels.len() {
            if !m.pixels[start] || seen[start] {
                continue;
            }
            count += 1;
            let mut stack = vec![start];
            seen[start] = true;
            while let Some(i) = stack.pop() {
                let (c, r) = (i as i64 % w, i as i64 / w);
                for dr in -1..=1 {
                    for dc in -1..=1 {
                        let diagonal = dr != 0 && dc != 0;
                        if (dr, dc) == (0, 0) || (diagonal && connectivity == Connectivity::Four) {
                            continue;
                        }
                        let (nc, nr) = (c + dc, r + dr);
                        if (0..w).contains(&nc) && (0..h).contains(&nr) {
                            let j = (nr * w + nc) as usize;
                            if m.pixels[j] && !seen[j] {
                                seen[j] = true;
                                stack.push(j);
                            }
                        }
                    }
                }
            }
        }
        count
    }

    proptest! {
        /// Labelling agrees with a flood fill, and neighbours share labels.
        #[test]
        fn labels_agree_with_flood_fill(w in 1u32..16, h in 1u32..16, bits in proptest::collection::vec(any::<bool>(), 256)) {
            let m = Mask { width: w, height: h, pixels: bits[..(w * h) as usize].to_vec() };
            for connectivity in [Connectivity::Four, Connectivity::Eight] {
                let (labels, count) = label(&m, connectivity);
                prop_assert_eq!(count, flood_count(&m, connectivity));
                for (i, &l) in labels.iter().enumerate() {
                    prop_assert_eq!(l != 0, m.pixels[i]);
                    let c = i % w as usize;
                    if l != 0 && c > 0 && labels[i - 1] != 0 {
                        prop_assert_eq!(labels[i - 1], l);
                    }
                }
                // Raster order of first pixels.
                let mut next = 1;
                for &l in &labels {
                    if l == next { next += 1; }
                    prop_assert!(l < next);
                }
            }
        }

        /// Moments summed run by run in closed form equal the pixel-by-pixel sums.
        #[test]
        fn run_moments_equal_pixel_moments(bits in proptest::collection::vec(any::<bool>(), 1..400), width in 1u32..40) {
            let height = (bits.len() as u32).div_ceil(width);
            let mut pixels = bits.clone();
            pixels.resize((width * height) as usize, false);
            let m = Mask { width, height, pixels };
            let (found, labels) = components(&m, Connectivity::Eight);
            for c in &found {
                let mut sums = Sums::default();
                for (i, &l) in labels.iter().enumerate() {
                    if l == c.label {
                        sums.add(i as u32 % width, i as u32 / width);
                    }
                }
                prop_assert_eq!(c.area, sums.m00);
                prop_assert_eq!(c.centroid, sums.centroid());
                prop_assert_eq!(c.hu, sums.shape().1);
                prop_assert_eq!(c.bbox, [sums.left, sums.top, sums.right - sums.left + 1, sums.bottom - sums.top + 1]);
            }
        }

        /// Hu invariants do not change when the shape is moved.
        #[test]
        fn hu_is_translation_invariant(bits in proptest::collection::vec(any::<bool>(), 36), dx in 0u32..5, dy in 0u32..5) {
            prop_assume!(bits.iter().any(|&b| b));
            let place = |ox: u32, oy: u32| {
                let mut m = Mask { width: 12, height: 12, pixels: vec![false; 144] };
                for (i, &b) in bits.iter().enumerate() {
                    let (x, y) = (i as u32 % 6 + ox, i as u32 / 6 + oy);
                    m.pixels[(y * 12 + x) as usize] = b;
                }
                let (found, _) = components(&m, Connectivity::Eight);
                let mut sums = Sums::default();
                for (i, &p) in m.pixels.iter().enumerate() {
                    if p { sums.add(i as u32 % 12, i as u32 / 12); }
                }
                (found.len(), sums.shape().1)
            };
            let (a, b) = (place(0, 0), place(dx, dy));
            prop_assert_eq!(a.0, b.0);
            for k in 0..7 {
                prop_assert!((a.1[k] - b.1[k]).abs() <= 1e-9 * (1.0 + a.1[k].abs()), "h{} {} vs {}", k + 1, a.1[k], b.1[k]);
            }
        }
    }
}
