//! Colour quantization for palette formats (MagicaVoxel `.vox` holds at most 255 colours): median cut in linear
//! RGB and alpha (a blended material's voxels keep theirs; every other voxel's is 255), weighted by how many voxels
//! carry each colour, then every colour mapped to its nearest palette entry.
//!
//! Linear space because averaging and distances there follow light, not the sRGB encoding; a grid with at most
//! 255 distinct colours keeps them exactly.

use crate::mesh::material::SRGB_TO_LINEAR;
use std::collections::HashMap;

/// A palette and, per input colour, its entry.
pub struct Quantized {
    pub palette: Vec<[u8; 4]>,
    pub index: Vec<u8>,
}

fn linear(c: [u8; 4]) -> [f32; 4] {
    let lut = &*SRGB_TO_LINEAR;
    [lut[c[0] as usize], lut[c[1] as usize], lut[c[2] as usize], f32::from(c[3]) / 255.0]
}

fn encode(l: [f32; 4]) -> [u8; 4] {
    let e = crate::voxel::cpu::colour::encode_srgb;
    [e(l[0]) as u8, e(l[1]) as u8, e(l[2]) as u8, (l[3] * 255.0).round().clamp(1.0, 255.0) as u8]
}

/// Quantizes `colours` (sRGB RGBA) to at most `max` (1..=255) palette entries.
pub fn quantize(colours: &[[u8; 4]], max: usize) -> Quantized {
    let max = max.clamp(1, 255);
    // Alpha 0 marks a voxel without colour (no triangle within reach): it is opaque, as every voxel but a blended
    // material's.
    let opaque = |c: &[u8; 4]| if c[3] == 0 { [c[0], c[1], c[2], 255] } else { *c };
    let mut counts: HashMap<[u8; 4], u64> = HashMap::new();
    for c in colours {
        *counts.entry(opaque(c)).or_default() += 1;
    }
    let mut unique: Vec<([u8; 4], u64)> = counts.into_iter().collect();
    // A fixed order, so the same grid always gets the same palette.
    unique.sort_unstable();
    let palette: Vec<[u8; 4]> =
        if unique.len() <= max { unique.iter().map(|(c, _)| *c).collect() } else { median_cut(&unique, max) };
    let lin: Vec<[f32; 4]> = palette.iter().map(|&p| linear(p)).collect();
    let nearest = |c: [u8; 4]| {
        let l = linear(c);
        let d = |p: &[f32; 4]| (0..4).map(|i| (p[i] - l[i]) * (p[i] - l[i])).sum::<f32>();
        (0..lin.len()).min_by(|&a, &b| d(&lin[a]).total_cmp(&d(&lin[b]))).unwrap_or(0) as u8
    };
    let lookup: HashMap<[u8; 4], u8> = unique.iter().map(|&(c, _)| (c, nearest(c))).collect();
    let index = colours.iter().map(|c| lookup.get(&opaque(c)).copied().unwrap_or(0)).collect();
    Quantized { palette, index }
}

/// Splits the weighted colour set into `max` boxes, each time the box with the widest channel range (times its
/// weight, so crowded boxes split first) at its weighted median, and returns each box's weighted mean.
fn median_cut(unique: &[([u8; 4], u64)], max: usize) -> Vec<[u8; 4]> {
    let mut items: Vec<([f32; 4], u64)> = unique.iter().map(|&(c, n)| (linear(c), n)).collect();
    // Boxes as ranges of `items`.
    let mut boxes: Vec<(usize, usize)> = vec![(0, items.len())];
    let spread = |items: &[([f32; 4], u64)]| -> (usize, f32) {
        (0..4)
            .map(|ch| {
                let (lo, hi) =
                    items.iter().fold((f32::MAX, f32::MIN), |(lo, hi), (c, _)| (lo.min(c[ch]), hi.max(c[ch])));
                (ch, hi - lo)
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0))
    };
    while boxes.len() < max {
        let score = |&(a, b): &(usize, usize)| {
            if b - a < 2 {
                return 0.0;
            }
            let weight: u64 = items[a..b].iter().map(|i| i.1).sum();
            spread(&items[a..b]).1 * (weight as f32).sqrt()
        };
        let Some((k, s)) = boxes.iter().map(score).enumerate().max_by(|a, b| a.1.total_cmp(&b.1)) else { break };
        if s <= 0.0 {
            break;
        }
        let (a, b) = boxes[k];
        let (ch, _) = spread(&items[a..b]);
        items[a..b].sort_by(|x, y| x.0[ch].total_cmp(&y.0[ch]));
        let total: u64 = items[a..b].iter().map(|i| i.1).sum();
        let mut acc = 0;
        let mut cut = a + 1;
        for (i, item) in items[a..b].iter().enumerate() {
            acc += item.1;
            if acc * 2 >= total {
                cut = (a + i + 1).clamp(a + 1, b - 1);
                break;
            }
        }
        boxes[k] = (a, cut);
        boxes.push((cut, b));
    }
    boxes
        .iter()
        .map(|&(a, b)| {
            let weight: u64 = items[a..b].iter().map(|i| i.1).sum();
            let mut sum = [0f64; 4];
            for (c, n) in &items[a..b] {
                for ch in 0..4 {
                    sum[ch] += c[ch] as f64 * *n as f64;
                }
            }
            encode(sum.map(|s| (s / weight.max(1) as f64) as f32))
        })
        .collect()
}
