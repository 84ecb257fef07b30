//! Exact linear algebra on incidence matrices.

/// Two Mersenne-size primes. The rank of an integer matrix modulo a prime
/// never exceeds its rank over the rationals and equals it unless the prime
/// divides every maximal non-zero minor; taking the larger of two ranks
/// modulo primes near 2⁶¹ makes a wrong answer practically impossible for
/// the small-entry matrices Petri nets have.
const PRIMES: [u64; 2] = [(1 << 61) - 1, 2_305_843_009_213_693_921];

/// The rank of `m` (rows of equal length) over the rationals.
pub fn rank(m: &[Vec<i64>]) -> usize {
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

    fn gcd(a: i128, b: i128) -> i128 {
        if b == 0 { a } else { gcd(b, a % b) }
    }

    #[test]
    fn known_ranks() {
        assert_eq!(rank(&[vec![1, -1, 0], vec![-1, 1, 0]]), 1);
        assert_eq!(rank(&[vec![1, 0], vec![0, 1], vec![1, 1]]), 2);
        assert_eq!(rank(&[]), 0);
    }

    proptest! {
        #[test]
        fn agrees_with_exact_elimination(
            m in proptest::collection::vec(proptest::collection::vec(-3i64..=3, 5), 0..6)
        ) {
            prop_assert_eq!(rank(&m), rank_exact(&m));
        }
    }
}
