//! Minimal semi-positive invariants by the Farkas algorithm with Martinez and
//! Silva's support test (1982).
//!
//! A P-invariant (P-semiflow) y ≥ 0, y ≠ 0 with yᵀC = 0 is a weighted token
//! count no firing changes; a T-invariant x ≥ 0 with Cx = 0 is a firing-count
//! vector that returns the net to where it started. The algorithm eliminates
//! one column of C at a time, combining every positive row with every negative
//! one, and drops any row whose support contains another row's: what is left
//! are the minimal-support invariants. Their number can grow exponentially,
//! so a limit on intermediate rows keeps a pathological net from eating the
//! machine.

use thiserror::Error;

use crate::net::Net;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum TooManyInvariants {
    #[error("more than {0} intermediate rows: the net has too many minimal invariants to list")]
    Rows(usize),
    #[error("invariant coefficients outgrew 64 bits")]
    Overflow,
}

/// One invariant: (index, coefficient) for each non-zero coefficient.
pub type Invariant = Vec<(usize, u64)>;

/// Minimal semi-positive P-invariants of `net` (indices are places).
pub fn p_invariants(net: &Net, max_rows: usize) -> Result<Vec<Invariant>, TooManyInvariants> {
    farkas(&net.incidence(), max_rows)
}

/// How many rows the Farkas tableau of `net`'s P-invariants may hold so
/// that it takes about `bytes`: a row holds an entry of 8 bytes per
/// transition and its combination of places (16 bytes an entry, a few at
/// first), and a step holds the rows before it beside those it makes.
/// Callers that only hope for the invariants (bounds, a verdict) cap their
/// search this way, so a net with too many of them costs little memory
/// before it is given up on.
pub fn p_rows_within(net: &Net, bytes: usize) -> usize {
    let row = 8 * net.transitions.len() + 4 * 16 + 128;
    bytes / (2 * row)
}

/// Minimal semi-positive T-invariants of `net` (indices are transitions).
pub fn t_invariants(net: &Net, max_rows: usize) -> Result<Vec<Invariant>, TooManyInvariants> {
    let c = net.incidence();
    let transposed: Vec<Vec<i64>> = (0..net.transitions.len())
        .map(|t| c.iter().map(|row| row[t]).collect())
        .collect();
    farkas(&transposed, max_rows)
}

/// Whether some y ≥ 1 (every place weighted) keeps yᵀ·m constant: true
/// exactly when the minimal P-invariants together cover every place.
pub fn is_conservative(places: usize, p_invariants: &[Invariant]) -> bool {
    let mut covered = vec![false; places];
    for inv in p_invariants {
        for &(p, _) in inv {
            covered[p] = true;
        }
    }
    covered.iter().all(|&c| c)
}

/// A row of the Farkas tableau: what is left of C, and the combination of
/// original rows it stands for, sparse (index, coefficient) in index order,
/// so a wide net's rows cost what they hold, not rows × rows.
#[derive(Clone)]
struct Row {
    c: Vec<i64>,
    combination: Vec<(u32, u64)>,
}

impl Row {
    /// Whether this row's support is a subset of `other`'s.
    fn support_within(&self, other: &Row) -> bool {
        let mut theirs = other.combination.iter().map(|&(i, _)| i);
        self.combination
            .iter()
            .all(|&(i, _)| theirs.by_ref().find(|&j| j >= i) == Some(i))
    }
}

/// Minimal semi-positive y with yᵀ·m = 0 for the rows of `m`.
fn farkas(m: &[Vec<i64>], max_rows: usize) -> Result<Vec<Invariant>, TooManyInvariants> {
    let cols = m.first().map_or(0, Vec::len);
    let mut rows: Vec<Row> = m
        .iter()
        .enumerate()
        .map(|(i, r)| Row {
            c: r.clone(),
            combination: vec![(i as u32, 1)],
        })
        .collect();
    let mut remaining: Vec<usize> = (0..cols).collect();
    while !remaining.is_empty() {
        // Eliminate first the column that creates the fewest new rows.
        let cost = |j: usize| {
            let positive = rows.iter().filter(|r| r.c[j] > 0).count();
            let negative = rows.iter().filter(|r| r.c[j] < 0).count();
            positive * negative
        };
        let pick = (0..remaining.len())
            .min_by_key(|&k| cost(remaining[k]))
            .expect("columns remain");
        let j = remaining.swap_remove(pick);
        let (zero, nonzero): (Vec<Row>, Vec<Row>) = rows.into_iter().partition(|r| r.c[j] == 0);
        let (positive, negative): (Vec<Row>, Vec<Row>) =
            nonzero.into_iter().partition(|r| r.c[j] > 0);
        let mut next = zero;
        for a in &positive {
            for b in &negative {
                let mut row = combine(a, b, j).ok_or(TooManyInvariants::Overflow)?;
                normalise(&mut row);
                next.push(row);
                if next.len() > max_rows {
                    return Err(TooManyInvariants::Rows(max_rows));
                }
            }
        }
        rows = minimal(next, m.len());
    }
    Ok(rows
        .into_iter()
        .map(|r| {
            r.combination
                .into_iter()
                .map(|(i, v)| (i as usize, v))
                .collect()
        })
        .collect())
}

/// |b_j|·a + |a_j|·b, which cancels column j; None on overflow.
fn combine(a: &Row, b: &Row, j: usize) -> Option<Row> {
    let (ka, kb) = (b.c[j].unsigned_abs(), a.c[j].unsigned_abs());
    let (ka_i, kb_i) = (i64::try_from(ka).ok()?, i64::try_from(kb).ok()?);
    let c =
        a.c.iter()
            .zip(&b.c)
            .map(|(&x, &y)| x.checked_mul(ka_i)?.checked_add(y.checked_mul(kb_i)?))
            .collect::<Option<Vec<i64>>>()?;
    // Both combinations are semi-positive: their sum has the union's support.
    let mut combination = Vec::with_capacity(a.combination.len() + b.combination.len());
    let (mut x, mut y) = (
        a.combination.iter().peekable(),
        b.combination.iter().peekable(),
    );
    loop {
        let entry = match (x.peek(), y.peek()) {
            (Some(&&(i, v)), Some(&&(k, w))) if i == k => {
                x.next();
                y.next();
                (i, v.checked_mul(ka)?.checked_add(w.checked_mul(kb)?)?)
            }
            (Some(&&(i, v)), Some(&&(k, _))) if i < k => {
                x.next();
                (i, v.checked_mul(ka)?)
            }
            (_, Some(&&(k, w))) => {
                y.next();
                (k, w.checked_mul(kb)?)
            }
            (Some(&&(i, v)), None) => {
                x.next();
                (i, v.checked_mul(ka)?)
            }
            (None, None) => break,
        };
        combination.push(entry);
    }
    Some(Row { c, combination })
}

/// Divides a row by the gcd of its entries, so equal invariants compare equal.
fn normalise(row: &mut Row) {
    let g = row.combination.iter().fold(0u64, |g, &(_, v)| gcd(g, v));
    let g = row.c.iter().fold(g, |g, &v| gcd(g, v.unsigned_abs()));
    if g > 1 {
        row.combination.iter_mut().for_each(|(_, v)| *v /= g);
        row.c.iter_mut().for_each(|v| *v /= g as i64);
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Keeps the rows whose support contains no other row's; of rows with equal
/// supports, the first.
fn minimal(mut rows: Vec<Row>, indices: usize) -> Vec<Row> {
    // Smaller supports first: a row can only be dominated by one no larger.
    rows.sort_by_key(|r| r.combination.len());
    // A kept row within r has its first index in r: look only at those.
    let mut by_first: Vec<Vec<usize>> = vec![Vec::new(); indices];
    let mut kept: Vec<Row> = Vec::with_capacity(rows.len());
    for r in rows {
        let dominated = r.combination.iter().any(|&(i, _)| {
            by_first[i as usize]
                .iter()
                .any(|&k| kept[k].support_within(&r))
        });
        if !dominated {
            if let Some(&(first, _)) = r.combination.first() {
                by_first[first as usize].push(kept.len());
            }
            kept.push(r);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cycle() -> Net {
        let mut n = Net::new("cycle");
        n.add_place("a", 1).unwrap();
        n.add_place("b", 0).unwrap();
        n.add_place("c", 0).unwrap();
        n.add_transition_with("ab", None, &[("a", 1)], &[("b", 1)])
            .unwrap();
        n.add_transition_with("bc", None, &[("b", 1)], &[("c", 2)])
            .unwrap();
        n.add_transition_with("ca", None, &[("c", 2)], &[("a", 1)])
            .unwrap();
        n
    }

    #[test]
    fn weighted_cycle() {
        let n = cycle();
        assert_eq!(
            p_invariants(&n, 1000).unwrap(),
            vec![vec![(0, 2), (1, 2), (2, 1)]]
        );
        assert_eq!(
            t_invariants(&n, 1000).unwrap(),
            vec![vec![(0, 1), (1, 1), (2, 1)]]
        );
        assert!(is_conservative(3, &p_invariants(&n, 1000).unwrap()));
    }
}
