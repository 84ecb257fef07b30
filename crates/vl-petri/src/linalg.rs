//! Exact linear algebra on incidence matrices.

/// Two Mersenne-size primes. The rank of an integer matrix modulo a prime
/// never exceeds its rank over the rationals and equals it unless the prime
/// divides every maximal non-zero minor; taking the larger of two ranks
/// modulo primes near 2⁶¹ makes a wrong answer practically impossible for
/// the small-entry matrices Petri nets have.
const PRIMES: [u64; 2] = [(1 << 61) - 1, 2_305_843_009_213_693_921];

/// The rank of `m` (rows of equal length) over the rationals.
pub(crate) fn rank(m: &[Vec<i64>]) -> usize {
    PRIMES.iter().map(|&p| rank_mod(m, p)).max().unwrap_or(0)
}

fn rank_mod(m: &[Vec<i64>], p: u64) -> usize {
    let cols = m.first().map_or(0, Vec::len);
    let reduce = |v: i64| v.rem_euclid(p as i64) as u64;
    let mut rows: Vec<Vec<u64>> = m
        .iter()
        .map(|r| r.iter().map(|&v| reduce(v)).collect())
        .collect();
    let mul = |a: u64, b: u64| ((u128::from(a) * u128::from(b)) % u128::from(p)) as u64;
    let mut rank = 0;
    for col in 0..cols {
        let Some(pivot) = (rank..rows.len()).find(|&r| rows[r][col] != 0) else {
            continue;
        };
        rows.swap(rank, pivot);
        let inverse = pow(rows[rank][col], p - 2, p);
        let pivot_row: Vec<u64> = rows[rank].iter().map(|&v| mul(v, inverse)).collect();
        for row in rows.iter_mut().skip(rank + 1) {
            let factor = row[col];
            if factor == 0 {
                continue;
            }
            for (cell, &pv) in row.iter_mut().zip(&pivot_row).skip(col) {
                *cell = (*cell + p - mul(factor, pv)) % p;
            }
        }
        rows[rank] = pivot_row;
        rank += 1;
    }
    rank
}

/// Which rows of `m`, taken in `order`, are not combinations of rows taken
/// before them over the rationals: a basis of the span of the rows in
/// `order`, its first rows preferred (row `r` is kept when `kept[r]`).
///
/// The arithmetic is exact (fraction-free elimination in 128 bits, each
/// row divided by its gcd). A row whose elimination would overflow is
/// kept, so a row said to be dependent always is one; a kept row may, in
/// that rare case, be dependent after all.
pub(crate) fn basis_rows(m: &[Vec<i64>], order: &[usize]) -> Vec<bool> {
    let mut kept = vec![false; m.len()];
    // Echelon rows, each as (its pivot column, its non-zero entries).
    let mut echelon: Vec<(usize, Vec<(usize, i128)>)> = Vec::new();
    let mut v: Vec<i128> = Vec::new();
    for &r in order {
        v.clear();
        v.extend(m[r].iter().map(|&x| i128::from(x)));
        // Each echelon row is zero at the pivots of the rows before it, so
        // one pass in order clears every pivot column of v.
        let reduced = echelon.iter().try_for_each(|(pivot, row)| {
            let x = v[*pivot];
            if x == 0 {
                return Some(());
            }
            let p = row.iter().find(|&&(c, _)| c == *pivot).map(|&(_, a)| a)?;
            if x % p == 0 {
                // The common case with unit pivots: no scaling of v.
                let f = x / p;
                for &(c, a) in row {
                    v[c] = v[c].checked_sub(f.checked_mul(a)?)?;
                }
            } else {
                for e in v.iter_mut() {
                    *e = e.checked_mul(p)?;
                }
                for &(c, a) in row {
                    v[c] = v[c].checked_sub(x.checked_mul(a)?)?;
                }
                let g = v.iter().fold(0i128, |g, &e| gcd(g, e.abs()));
                if g > 1 {
                    v.iter_mut().for_each(|e| *e /= g);
                }
            }
            Some(())
        });
        if reduced.is_none() {
            kept[r] = true;
            continue;
        }
        let Some(pivot) = v.iter().position(|&e| e != 0) else {
            continue;
        };
        kept[r] = true;
        let g = v.iter().fold(0i128, |g, &e| gcd(g, e.abs()));
        let row = v
            .iter()
            .enumerate()
            .filter(|&(_, &e)| e != 0)
            .map(|(c, &e)| (c, e / g))
            .collect();
        echelon.push((pivot, row));
    }
    kept
}

fn gcd(a: i128, b: i128) -> i128 {
    if b == 0 { a } else { gcd(b, a % b) }
}

fn pow(mut base: u64, mut exp: u64, p: u64) -> u64 {
    let mut acc = 1u64;
    while exp > 0 {
        if exp & 1 == 1 {
            acc = ((u128::from(acc) * u128::from(base)) % u128::from(p)) as u64;
        }
        base = ((u128::from(base) * u128::from(base)) % u128::from(p)) as u64;
        exp >>= 1;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Rank by exact fraction-free elimination in i128 (fine for small matrices).
    fn rank_exact(m: &[Vec<i64>]) -> usize {
        let mut a: Vec<Vec<i128>> = m
            .iter()
            .map(|r| r.iter().map(|&v| i128::from(v)).collect())
            .collect();
        let cols = a.first().map_or(0, Vec::len);
        let mut rank = 0;
        for col in 0..cols {
            let Some(p) = (rank..a.len()).find(|&r| a[r][col] != 0) else {
                continue;
            };
            a.swap(rank, p);
            let pivot = a[rank].clone();
            for row in a.iter_mut().skip(rank + 1) {
                let y = row[col];
                for (cell, &pv) in row.iter_mut().zip(&pivot) {
                    *cell = *cell * pivot[col] - pv * y;
                }
                let g = row.iter().fold(0i128, |g, &v| gcd(g, v.abs()));
                if g > 1 {
                    row.iter_mut().for_each(|v| *v /= g);
                }
            }
            rank += 1;
        }
        rank
    }

    #[test]
    fn known_ranks() {
        assert_eq!(rank(&[vec![1, -1, 0], vec![-1, 1, 0]]), 1);
        assert_eq!(rank(&[vec![1, 0], vec![0, 1], vec![1, 1]]), 2);
        assert_eq!(rank(&[]), 0);
    }

    #[test]
    fn a_basis_prefers_the_rows_taken_first() {
        // Row 2 is row 0 + row 1; row 3 is twice row 1.
        let m = vec![
            vec![1, 0, -1],
            vec![0, 1, -1],
            vec![1, 1, -2],
            vec![0, 2, -2],
        ];
        assert_eq!(basis_rows(&m, &[0, 1, 2, 3]), [true, true, false, false]);
        assert_eq!(basis_rows(&m, &[3, 2, 1, 0]), [false, false, true, true]);
        assert_eq!(basis_rows(&m, &[2, 3]), [false, false, true, true]);
    }

    proptest! {
        /// The rows kept are as many as the rank, and every row left out
        /// is a combination of the rows kept: adding it changes no rank.
        #[test]
        fn a_basis_spans_every_row_it_leaves_out(
            m in proptest::collection::vec(proptest::collection::vec(-3i64..=3, 5), 0..8),
            seed in any::<u64>(),
        ) {
            let mut order: Vec<usize> = (0..m.len()).collect();
            let mut x = seed | 1;
            for i in (1..order.len()).rev() {
                x ^= x << 13; x ^= x >> 7; x ^= x << 17;
                order.swap(i, (x % (i as u64 + 1)) as usize);
            }
            let kept = basis_rows(&m, &order);
            let basis: Vec<Vec<i64>> = (0..m.len()).filter(|&r| kept[r]).map(|r| m[r].clone()).collect();
            prop_assert_eq!(basis.len(), rank_exact(&m));
            for r in (0..m.len()).filter(|&r| !kept[r]) {
                let mut with = basis.clone();
                with.push(m[r].clone());
                prop_assert_eq!(rank_exact(&with), basis.len());
            }
        }

        #[test]
        fn agrees_with_exact_elimination(
            m in proptest::collection::vec(proptest::collection::vec(-3i64..=3, 5), 0..6)
        ) {
            prop_assert_eq!(rank(&m), rank_exact(&m));
        }
    }
}
