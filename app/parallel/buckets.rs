//! A stable sort of integers by their high bits that moves each one once a pass, on every thread: a radix sort of
//! digits of up to [`DIGIT_BITS`] bits, least significant first. Where the keys are few (a field's bricks), one
//! pass places every integer, where a comparison sort passes over all of them at every level that does not fit a
//! cache.

use super::prelude::*;

/// The widest digit a pass places: its counts (a word per digit and thread) stay small beside the integers.
pub const DIGIT_BITS: u32 = 16;

/// Sorts `items` by `item >> shift`, keeping the order of items with the same key; `key_bits` is how many bits
/// the keys have (the bits above `shift + key_bits` are taken as zero).
pub fn sort_by_high_bits(items: &mut Vec<u64>, shift: u32, key_bits: u32) {
    let mut low = 0;
    while low < key_bits {
        let bits = (key_bits - low).min(DIGIT_BITS);
        *items = place_by_digit(items, shift + low, bits);
        low += bits;
    }
}

/// One pass: `items` stably by the digit of `bits` bits at `at`. Each thread counts its own stretch of the items,
/// then places them in its own stretch of each digit's run, so no two threads write one place.
fn place_by_digit(items: &[u64], at: u32, bits: u32) -> Vec<u64> {
    let digit = |v: u64| ((v >> at) & ((1u64 << bits) - 1)) as usize;
    let part = items.len().div_ceil(super::threads().max(1)).max(1);
    let parts: Vec<&[u64]> = items.chunks(part).collect();
    let counts: Vec<Vec<usize>> = parts
        .par_iter()
        .map(|part| {
            let mut count = vec![0usize; 1 << bits];
            part.iter().for_each(|&v| count[digit(v)] += 1);
            count
        })
        .collect();
    let mut out = vec![0u64; items.len()];
    // Each part's stretch of each digit's run, digit by digit: the output cut into them in order.
    let mut stretches: Vec<Vec<&mut [u64]>> = parts.iter().map(|_| Vec::with_capacity(1 << bits)).collect();
    let mut rest: &mut [u64] = &mut out;
    for d in 0..1 << bits {
        for (p, count) in counts.iter().enumerate() {
            let (stretch, tail) = std::mem::take(&mut rest).split_at_mut(count[d]);
            stretches[p].push(stretch);
            rest = tail;
        }
    }
    parts.par_iter().zip(stretches.par_iter_mut()).for_each(|(part, stretches)| {
        let mut filled = vec![0usize; 1 << bits];
        for &v in part.iter() {
            let d = digit(v);
            stretches[d][filled[d]] = v;
            filled[d] += 1;
        }
    });
    out
}
