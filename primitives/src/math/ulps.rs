//! Stepping a float by a number of ulps (units in the last place) towards −∞ or +∞: what an
//! enclosure widens its bounds by where a library function or a chain of roundings is off by a
//! known number of ulps.

/// `x` stepped `ulps` floats towards −∞: `ulps` calls of [`f64::next_down`], the same bits.
#[inline(always)]
pub(crate) fn down(x: f64, ulps: u32) -> f64 {
    // the bit patterns of floats of one sign are ordered as their magnitudes: `ulps` steps down
    // are `ulps` patterns towards −∞, as long as the steps neither cross zero nor pass ±∞
    let (bits, steps) = (x.to_bits(), u64::from(ulps));
    if x > 0.0 && bits > steps {
        return f64::from_bits(bits - steps);
    }
    if x < 0.0 && (bits & !SIGN_BIT) + steps <= INFINITY_BITS {
        return f64::from_bits(bits + steps);
    }
    let mut x = x;
    for _ in 0..ulps {
        x = x.next_down();
    }
    x
}

/// `x` stepped `ulps` floats towards +∞: `ulps` calls of [`f64::next_up`], the same bits.
#[inline(always)]
pub(crate) fn up(x: f64, ulps: u32) -> f64 {
    // as `down`, towards +∞
    let (bits, steps) = (x.to_bits(), u64::from(ulps));
    if x < 0.0 && (bits & !SIGN_BIT) > steps {
        return f64::from_bits(bits - steps);
    }
    if x > 0.0 && bits + steps <= INFINITY_BITS {
        return f64::from_bits(bits + steps);
    }
    let mut x = x;
    for _ in 0..ulps {
        x = x.next_up();
    }
    x
}

/// The sign bit of an f64, and the pattern of +∞.
const SIGN_BIT: u64 = 1 << 63;
const INFINITY_BITS: u64 = 0x7FF0_0000_0000_0000;

#[cfg(test)]
mod tests {
    use super::*;

    /// `down` and `up` step by bit patterns where they can: the same bits as stepping one float
    /// at a time (`next_down` / `next_up`), for 0 to 12 steps, at zeros, subnormals, the ends of
    /// binades, the largest floats, infinities, NaN and random patterns of both signs.
    #[test]
    fn steps_by_bits_equal_steps_one_float_at_a_time() {
        let mut xs = vec![
            0.0,
            -0.0,
            f64::from_bits(1),
            f64::from_bits(5),
            f64::from_bits(12),
            f64::from_bits(13),
            f64::MIN_POSITIVE,
            1.0,
            2.0,
            f64::MAX,
            f64::from_bits(INFINITY_BITS - 3),
            f64::INFINITY,
            f64::NAN,
        ];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            xs.push(f64::from_bits(state));
        }
        let negated: Vec<f64> = xs.iter().map(|x| -x).collect();
        xs.extend(negated);
        for &x in &xs {
            let (mut d, mut u) = (x, x);
            for ulps in 0..=12 {
                assert_eq!(down(x, ulps).to_bits(), d.to_bits(), "down({x:e}, {ulps})");
                assert_eq!(up(x, ulps).to_bits(), u.to_bits(), "up({x:e}, {ulps})");
                (d, u) = (d.next_down(), u.next_up());
            }
        }
    }
}
