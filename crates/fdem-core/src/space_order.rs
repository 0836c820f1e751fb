//! Orders points along a space-filling curve (the Morton, or Z-order, curve), so that
//! items numbered in that order lie near each other in memory when they lie near each
//! other in space.

/// Bits per axis of a Morton code (3 x 21 = 63 bits).
const BITS: u32 = 21;

/// The order of `points` along the Morton curve over their bounding box: `order[i]` is
/// the index of the `i`-th point on the curve. Points with the same code keep their
/// index order; non-finite coordinates count as the box's lower corner.
pub fn morton_order(points: &[[f64; 3]]) -> Vec<usize> {
    let codes = morton_codes(points);
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| (codes[i], i));
    order
}

/// Morton codes of `points`, each coordinate quantised on [`BITS`] bits over the points'
/// bounding box.
pub fn morton_codes(points: &[[f64; 3]]) -> Vec<u64> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for d in 0..3 {
            if p[d].is_finite() {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
    }
    let cells = f64::from((1u32 << BITS) - 1);
    let scale: [f64; 3] = std::array::from_fn(|d| {
        let extent = hi[d] - lo[d];
        if extent > 0.0 { cells / extent } else { 0.0 }
    });
    points
        .iter()
        .map(|p| {
            let q: [u64; 3] = std::array::from_fn(|d| {
                // NaN and values below the box saturate to 0 in the cast.
                (((p[d] - lo[d]) * scale[d]) as u64).min(cells as u64)
            });
            spread_bits(q[0]) | (spread_bits(q[1]) << 1) | (spread_bits(q[2]) << 2)
        })
        .collect()
}

/// The low [`BITS`] bits of `x`, two zero bits inserted after each.
fn spread_bits(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_bits_interleaves() {
        assert_eq!(spread_bits(0b1), 0b1);
        assert_eq!(spread_bits(0b11), 0b1001);
        assert_eq!(spread_bits(0b101), 0b100_0001);
        assert_eq!(spread_bits((1 << BITS) - 1), 0x1249_2492_4924_9249);
    }

    /// On a 4 x 4 x 4 grid the curve visits the eight points of each 2 x 2 x 2 octant in a
    /// row, and the octants in Z order.
    #[test]
    fn the_curve_visits_octants_in_turn() {
        let mut points = Vec::new();
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    points.push([f64::from(x), f64::from(y), f64::from(z)]);
                }
            }
        }
        let order = morton_order(&points);
        for (block, chunk) in order.chunks(8).enumerate() {
            let octant = |p: [f64; 3]| {
                usize::from(p[0] >= 2.0)
                    | usize::from(p[1] >= 2.0) << 1
                    | usize::from(p[2] >= 2.0) << 2
            };
            for &i in chunk {
                assert_eq!(octant(points[i]), block, "{:?}", points[i]);
            }
        }
    }

    #[test]
    fn ties_and_degenerate_boxes_keep_index_order() {
        let points = [[1.0, 2.0, 3.0]; 4];
        assert_eq!(morton_order(&points), vec![0, 1, 2, 3]);
        let flat = [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, f64::NAN]];
        assert_eq!(morton_order(&flat), vec![1, 2, 0]);
        assert!(morton_order(&[]).is_empty());
    }
}
