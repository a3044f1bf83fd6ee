//! Gaussian image pyramids (Tong §5.1: "an image pyramid for each image of the BTF sample").

/// Halves an interleaved image (`channels` values per pixel) after a 5-tap binomial blur
/// [1 4 6 4 1]/16 in each direction; borders mirror, or wrap when `tileable`. The result is
/// ⌈w/2⌉ × ⌈h/2⌉.
pub fn downsample(
    image: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    tileable: bool,
) -> (Vec<f32>, usize, usize) {
    const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let (w2, h2) = (width.div_ceil(2), height.div_ceil(2));
    // Horizontal pass at the kept columns, then vertical at the kept rows.
    let mut rows = vec![0.0f32; w2 * height * channels];
    for y in 0..height {
        for x2 in 0..w2 {
            for (t, tap) in TAPS.iter().enumerate() {
                let sx = border(2 * x2 as isize + t as isize - 2, width, tileable);
                for c in 0..channels {
                    rows[(y * w2 + x2) * channels + c] += tap * image[(y * width + sx) * channels + c];
                }
            }
        }
    }
    let mut out = vec![0.0f32; w2 * h2 * channels];
    for y2 in 0..h2 {
        for (t, tap) in TAPS.iter().enumerate() {
            let sy = border(2 * y2 as isize + t as isize - 2, height, tileable);
            for i in 0..w2 * channels {
                out[y2 * w2 * channels + i] += tap * rows[sy * w2 * channels + i];
            }
        }
    }
    (out, w2, h2)
}

/// Index `i` brought into 0..n by mirroring (edge pixel not repeated) or wrapping.
fn border(i: isize, n: usize, tileable: bool) -> usize {
    let n = n as isize;
    if tileable {
        return i.rem_euclid(n) as usize;
    }
    if n == 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let m = i.rem_euclid(period);
    (if m < n { m } else { period - m }) as usize
}

/// Sizes of `levels` pyramid levels starting at `width × height`.
pub fn level_sizes(width: usize, height: usize, levels: usize) -> Vec<(usize, usize)> {
    std::iter::successors(Some((width, height)), |&(w, h)| Some((w.div_ceil(2), h.div_ceil(2))))
        .take(levels)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_images_stay_constant_and_sizes_halve() {
        let img = vec![0.25f32; 7 * 5 * 3];
        for tileable in [false, true] {
            let (out, w, h) = downsample(&img, 7, 5, 3, tileable);
            assert_eq!((w, h), (4, 3));
            assert!(out.iter().all(|&v| (v - 0.25).abs() < 1e-6));
        }
        assert_eq!(level_sizes(64, 48, 3), vec![(64, 48), (32, 24), (16, 12)]);
    }

    #[test]
    fn mirroring_and_wrapping_indices() {
        assert_eq!(
            (border(-1, 5, false), border(-2, 5, false), border(5, 5, false), border(6, 5, false)),
            (1, 2, 3, 2)
        );
        assert_eq!((border(-1, 5, true), border(5, 5, true)), (4, 0));
        assert_eq!(border(-3, 1, false), 0);
    }

    #[test]
    fn a_checkerboard_blurs_to_its_mean() {
        let img: Vec<f32> = (0..16 * 16).map(|p| ((p % 16 + p / 16) % 2) as f32).collect();
        let (out, _, _) = downsample(&img, 16, 16, 1, true);
        assert!(out.iter().all(|&v| (v - 0.5).abs() < 0.13), "{out:?}");
    }
}
