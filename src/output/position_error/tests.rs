use super::*;
use crate::draw::{flag_bits, NO_OBJECT};

const OBJECT: u32 = 3;

/// A smooth, curved map pixel -> P (metres): what a pool floor seen in perspective looks like.
fn smooth_position(x: f64, y: f64) -> [f32; 3] {
    [
        (0.01 * x + 2e-5 * x * x) as f32,
        (-0.5 - 0.004 * y + 1e-5 * x * y) as f32,
        (1.0 + 0.012 * y + 3e-5 * y * y) as f32,
    ]
}

/// A frame whose pixel (x, y) sees `position(x, y)` on object `OBJECT`.
fn frame_of(width: u32, height: u32, position: impl Fn(f64, f64) -> [f32; 3]) -> RenderedFrame {
    let pixels = (width * height) as usize;
    let mut frame = RenderedFrame {
        width,
        height,
        beauty_rgba: vec![[0.5, 0.5, 0.5, 1.0]; pixels],
        depth_m: vec![3.0; pixels],
        position: Vec::with_capacity(pixels),
        flags: vec![0; pixels],
        object: vec![OBJECT; pixels],
        ..Default::default()
    };
    for y in 0..height {
        for x in 0..width {
            frame.position.push(position(x as f64, y as f64));
        }
    }
    frame
}

fn compare(a: &RenderedFrame, b: &RenderedFrame) -> PositionComparison {
    compare_positions(a, b, &CompareOptions::default()).unwrap()
}

fn every_summary(c: &PositionComparison) -> Vec<PositionError> {
    [c.a_to_b, c.b_to_a, c.both]
        .iter()
        .flat_map(|s| [s.all, s.outside_flagged, s.outside_fold_band])
        .collect()
}

#[test]
fn a_frame_against_itself_is_exactly_zero_both_ways() {
    let frame = frame_of(48, 32, smooth_position);
    let comparison = compare(&frame, &frame);
    assert_eq!(comparison.object_mismatch_fraction, 0.0);
    assert_eq!(comparison.fold_edges, 0);
    for summary in every_summary(&comparison) {
        assert_eq!(summary.mean_px, 0.0);
        assert_eq!(summary.p99_px, 0.0);
        assert_eq!(summary.max_px, 0.0);
        assert_eq!(summary.unseen, 0);
    }
    assert_eq!(comparison.a_to_b.all.counted, 48 * 32);
    assert_eq!(comparison.both.all.counted, 2 * 48 * 32);
}

/// The errors of pixels whose match lies inside the other frame (not at its border).
fn interior_errors(
    from: &RenderedFrame,
    to: &RenderedFrame,
    shift: (f64, f64),
    reach: f64,
) -> Vec<f64> {
    let map = PositionMap::build(to);
    let (width, height) = (from.width as f64, from.height as f64);
    let mut errors = Vec::new();
    for y in 0..from.height {
        for x in 0..from.width {
            let (tx, ty) = (x as f64 + shift.0, y as f64 + shift.1);
            if tx < reach || ty < reach || tx > width - 1.0 - reach || ty > height - 1.0 - reach {
                continue;
            }
            let index = (y * from.width + x) as usize;
            let place = map
                .place_of(from.position[index], OBJECT, [x as f64, y as f64])
                .unwrap();
            assert!(place.seen, "({x}, {y}) not seen");
            errors.push((place.screen[0] - x as f64).hypot(place.screen[1] - y as f64));
        }
    }
    errors
}

/// B sees at (x, y) what A sees at (x + shift, y): every pixel of A is found `shift` px away, and
/// every pixel of B too.
#[test]
fn a_known_sub_pixel_shift_is_measured_both_ways() {
    for (shift_x, shift_y) in [(0.3, 0.0), (0.0, -0.3), (0.21, 0.17), (1.6, 0.0)] {
        let a = frame_of(64, 48, smooth_position);
        let b = frame_of(64, 48, |x, y| smooth_position(x + shift_x, y + shift_y));
        let expected = f64::hypot(shift_x, shift_y);
        let comparison = compare(&a, &b);
        assert_eq!(comparison.a_to_b.all.counted, 64 * 48);
        for direction in [comparison.a_to_b, comparison.b_to_a] {
            assert!(
                (direction.all.p99_px - expected).abs() < 0.01,
                "shift ({shift_x}, {shift_y}): p99 {} vs {expected}",
                direction.all.p99_px
            );
        }
        for (from, to, shift) in [(&a, &b, (-shift_x, -shift_y)), (&b, &a, (shift_x, shift_y))] {
            let worst = interior_errors(from, to, shift, 1.0)
                .iter()
                .map(|e| (e - expected).abs())
                .fold(0.0, f64::max);
            assert!(
                worst < 0.01,
                "shift ({shift_x}, {shift_y}): worst interior error off by {worst}"
            );
        }
    }
}

/// No window: a shift of 100 px is measured as 100 px, and A's pixels whose point B does not show
/// at all are measured to the nearest point B shows, and counted as unseen.
#[test]
fn errors_of_any_size_are_measured() {
    let (width, height) = (160, 12);
    let a = frame_of(width, height, smooth_position);
    let b = frame_of(width, height, |x, y| smooth_position(x + 100.0, y));
    let comparison = compare(&a, &b);
    let a_to_b = comparison.a_to_b.all;
    assert_eq!(a_to_b.counted, (width * height) as usize);
    // Pixels x < 100 of A show points B does not (it starts at A's x = 100).
    assert_eq!(a_to_b.unseen, 100 * height as usize);
    assert!((a_to_b.max_px - 100.0).abs() < 0.01, "{a_to_b:?}");
    let seen = interior_errors(&a, &b, (-100.0, 0.0), 0.0);
    assert_eq!(seen.len(), 60 * height as usize);
    assert!(seen.iter().all(|e| (e - 100.0).abs() < 0.01), "{seen:?}");
}

/// Pixels seeing another object in B are not measured but counted as mismatched; flagged pixels
/// are left out of the second summary only, from the frame the options name.
#[test]
fn object_mismatch_and_flags_are_counted() {
    let a = frame_of(20, 10, smooth_position);
    let mut b = a.clone();
    for index in 0..20 {
        b.object[index] = OBJECT + 1; // the top row sees another object
    }
    b.object[25] = NO_OBJECT;
    let mut b_flagged = b.clone();
    for index in 40..50 {
        b_flagged.flags[index] = flag_bits::CONVERGENCE;
    }
    let from_b = compare_positions(&a, &b_flagged, &CompareOptions::default()).unwrap();
    assert_eq!(from_b.flags_from, Side::B);
    assert_eq!(from_b.object_mismatch_fraction, 21.0 / 200.0);
    assert_eq!(from_b.object_mismatch_pixels, 21);
    assert_eq!(from_b.flagged_pixels, 10);
    assert_eq!(from_b.a_to_b.all.counted, 200 - 21);
    assert_eq!(from_b.a_to_b.outside_flagged.counted, 200 - 21 - 10);
    assert_eq!(from_b.b_to_a.outside_flagged.counted, 200 - 21 - 10);
    assert_eq!(from_b.a_to_b.all.max_px, 0.0);
    // A's flags are empty: "outside flagged" is then everything.
    let options = CompareOptions {
        flags_from: Side::A,
        ..CompareOptions::default()
    };
    let from_a = compare_positions(&a, &b_flagged, &options).unwrap();
    assert_eq!(from_a.flagged_pixels, 0);
    assert_eq!(from_a.a_to_b.outside_flagged, from_a.a_to_b.all);
}

/// A frame with nothing seen and differently sized or layer-less frames.
#[test]
fn bad_inputs_are_errors_and_empty_frames_count_nothing() {
    let a = frame_of(8, 6, smooth_position);
    let b = frame_of(8, 5, smooth_position);
    let options = CompareOptions::default();
    assert!(matches!(
        compare_positions(&a, &b, &options),
        Err(PositionErrorInput::Size(_))
    ));
    let mut old = a.clone();
    old.object.clear();
    let message = compare_positions(&a, &old, &options)
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with("B has no usable object-id layer"),
        "{message}"
    );
    let mut sky = a.clone();
    sky.object.fill(NO_OBJECT);
    let error = position_error(&sky, &sky).unwrap();
    assert_eq!(error.counted, 0);
    assert_eq!(error.mean_px, 0.0);
}

/// Part of the object hidden behind itself: P jumps between two rows of the same object. The
/// pixels next to the jump are still measured from the side they belong to, and the jump is not a
/// fold.
#[test]
fn a_jump_in_p_within_one_object_does_not_spoil_the_fit() {
    let jump = |p: [f32; 3], y: f64| {
        if y >= 20.0 {
            [p[0] + 0.05, p[1], p[2] + 0.3]
        } else {
            p
        }
    };
    let a = frame_of(48, 40, |x, y| jump(smooth_position(x, y), y));
    // The same shift on both sides, the jump staying put.
    let b = frame_of(48, 40, |x, y| jump(smooth_position(x, y + 0.3), y));
    let map = PositionMap::build(&b);
    let mut worst: f64 = 0.0;
    for y in 18..22u32 {
        for x in 1..47u32 {
            let index = (y * 48 + x) as usize;
            let place = map
                .place_of(a.position[index], OBJECT, [x as f64, y as f64])
                .unwrap();
            let error = (place.screen[0] - x as f64).hypot(place.screen[1] - y as f64);
            // B at row y' sees what A sees at y' + 0.3: row 20's point (the first of the lower
            // side) would be at y' = 19.7, across the jump, where B shows the upper side. B does
            // not see it; it is measured to the nearest point B shows, on the lower side's edge
            // (row 20), never on the upper side.
            if y == 20 {
                assert!(!place.seen, "({x}, {y}): {place:?}");
                assert!(
                    (place.screen[1] - 20.0).abs() < 1e-6
                        && (place.screen[0] - x as f64).abs() < 0.01,
                    "({x}, {y}): {place:?}"
                );
            } else {
                assert!(place.seen, "({x}, {y}): {place:?}");
                worst = worst.max((error - 0.3).abs());
            }
        }
    }
    assert!(worst < 0.01, "rows beside the jump off by {worst} px");
    assert_eq!(compare(&a, &b).fold_edges, 0);
}

/// A sheet folded along the column x = 40: A sees the strip x > 40's points again, mirrored, left
/// of it (P = s |x - 40|), as a convergence zone of the reference does. B draws one image only,
/// continuing to the left with points A never shows. A -> B measures each undrawn image at its
/// true distance, up to 80 px (no window); B -> A finds B's extra points unseen; the fold is
/// found at x = 40 and its band is the pixels within 1.5 px of it.
#[test]
fn an_undrawn_image_costs_its_distance_and_the_fold_is_banded() {
    let (width, height) = (96u32, 10u32);
    let s = 0.01;
    let a = frame_of(width, height, |x, y| {
        [(s * (x - 40.0).abs()) as f32, 0.0, (s * y) as f32]
    });
    let b = frame_of(width, height, |x, y| {
        [(s * (x - 40.0)) as f32, 0.0, (s * y) as f32]
    });
    let comparison = compare(&a, &b);
    assert!(comparison.fold_edges >= (height - 1) as usize);
    let band = fold::fold_band(&PositionMap::build(&a), width, height);
    for y in 0..height {
        for x in 0..width {
            let expected = (x as f64 - 40.0).abs() <= FOLD_BAND_PX;
            assert_eq!(band.mask[(y * width + x) as usize], expected, "({x}, {y})");
        }
    }
    // Pixel x < 40 of A sees the point B shows at 80 - x.
    let map_b = PositionMap::build(&b);
    for x in [0u32, 10, 30, 38] {
        let index = (5 * width + x) as usize;
        let place = map_b
            .place_of(a.position[index], OBJECT, [x as f64, 5.0])
            .unwrap();
        assert!(place.seen);
        let expected = 80.0 - 2.0 * x as f64;
        assert!(
            (place.screen[0] - x as f64 - expected).abs() < 1e-6,
            "x {x}: {place:?}"
        );
    }
    assert!((comparison.a_to_b.all.max_px - 80.0).abs() < 1e-6);
    assert_eq!(comparison.a_to_b.all.unseen, 0);
    assert_eq!(comparison.b_to_a.all.unseen, 40 * height as usize);
    // Outside the band the pairs with an end at x = 39..41 are gone.
    let outside = comparison.a_to_b.outside_fold_band;
    assert_eq!(
        comparison.a_to_b.all.counted - outside.counted,
        3 * height as usize
    );
}

/// A flat floor 1 m under a cosine wave (amplitude 4 cm, wavelength 0.5 m), seen straight down by
/// an orthographic camera, 128 px to the metre: the wave focuses, and the floor's map folds where
/// dX/dx = 0, X being where the refracted ray from surface point x meets the floor. Those places
/// are found here independently (Snell's law in vector form, a fine scan and bisection), and the
/// fold band must hold every one of them and no pixel further than 1 px beyond its width.
#[test]
fn the_folds_of_a_focusing_wave_are_where_optics_puts_them() {
    let (amplitude, wavenumber, depth, eta) = (0.04, std::f64::consts::TAU / 0.5, 1.0, 0.75);
    let metres_per_px = 1.0 / 128.0;
    let floor_x = |x: f64| {
        let slope = -amplitude * wavenumber * (wavenumber * x).sin();
        let height = amplitude * (wavenumber * x).cos();
        let norm = (slope * slope + 1.0).sqrt();
        let (nx, ny) = (-slope / norm, 1.0 / norm);
        // Incident (0, -1): cos_i = ny; t = eta d + (eta cos_i - cos_t) n.
        let cos_i = ny;
        let cos_t = (1.0 - eta * eta * (1.0 - cos_i * cos_i)).sqrt();
        let k = eta * cos_i - cos_t;
        let (tx, ty) = (k * nx, -eta + k * ny);
        x + tx * (height + depth) / -ty
    };
    let (width, height) = (128u32, 8u32);
    let frame = frame_of(width, height, |x, y| {
        [
            floor_x(x * metres_per_px) as f32,
            -depth as f32,
            (y * metres_per_px) as f32,
        ]
    });
    // dX/dx by central differences on a grid 100 times finer than the pixels; its zeros bisected.
    let derivative = |x: f64| (floor_x(x + 1e-7) - floor_x(x - 1e-7)) / 2e-7;
    let mut folds_px = Vec::new();
    let step = metres_per_px / 100.0;
    let mut x = 0.0;
    while x + step <= (width - 1) as f64 * metres_per_px {
        if derivative(x).signum() != derivative(x + step).signum() {
            let (mut lo, mut hi) = (x, x + step);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if derivative(mid).signum() == derivative(lo).signum() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            folds_px.push(0.5 * (lo + hi) / metres_per_px);
        }
        x += step;
    }
    assert_eq!(
        folds_px.len(),
        4,
        "two wavelengths, two folds each: {folds_px:?}"
    );
    let band = fold::fold_band(&PositionMap::build(&frame), width, height);
    for y in 0..height {
        for &fold in &folds_px {
            for x in [fold.floor(), fold.ceil()] {
                assert!(
                    band.mask[(y * width + x as u32) as usize],
                    "pixel ({x}, {y}) beside the fold at {fold:.3} is not in the band"
                );
            }
        }
        for x in 0..width {
            if band.mask[(y * width + x) as usize] {
                let nearest = folds_px
                    .iter()
                    .map(|f| (f - x as f64).abs())
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    nearest <= FOLD_BAND_PX + 1.0,
                    "pixel ({x}, {y}) is {nearest:.2} px from the nearest fold"
                );
            }
        }
    }
}

/// The pool's floor meeting its wall (90 degrees) and a box's edge are creases, not folds.
#[test]
fn a_crease_is_not_a_fold() {
    // A floor (y = 0) for rows y < 20, then a wall rising from it (z fixed).
    let frame = frame_of(40, 40, |x, y| {
        if y < 20.0 {
            [(0.01 * x) as f32, 0.0, (0.01 * (20.0 - y)) as f32]
        } else {
            [(0.01 * x) as f32, (0.01 * (y - 20.0)) as f32, 0.0]
        }
    });
    assert_eq!(compare(&frame, &frame).fold_edges, 0);
}

#[test]
fn water_pixels_are_those_of_the_water_matte() {
    let mut frame = frame_of(4, 1, |x, _| [x as f32, 0.0, -4.0]);
    assert_eq!(water_pixels(&frame, Vec3::ZERO), vec![false; 4]);
    frame.water_matte = vec![0.0, 1.0, 1.0, 0.0];
    assert_eq!(
        water_pixels(&frame, Vec3::ZERO),
        vec![false, true, true, false]
    );
}

/// A method that draws a patch of the floor 40 px from where it is (an 8x8 block of B shows the
/// points A shows 40 px to its right) both misses the patch's own points and shows the others
/// twice. B -> A measures each of the block's 64 pixels at exactly 40 px, and nothing else;
/// A -> B finds the 64 points B no longer shows unseen. The figures are worked out by hand here,
/// not by the code under test.
#[test]
fn a_patch_drawn_40_px_away_costs_40_px_one_way_and_is_unseen_the_other() {
    let (width, height) = (96u32, 32u32);
    // A plane seen face-on: 1 cm per pixel.
    let plane = |x: f64, y: f64| [(0.01 * x) as f32, (0.01 * y) as f32, 2.0];
    let in_block = |x: f64, y: f64| (10.0..18.0).contains(&x) && (12.0..20.0).contains(&y);
    let a = frame_of(width, height, plane);
    let b = frame_of(width, height, |x, y| {
        if in_block(x, y) {
            plane(x + 40.0, y)
        } else {
            plane(x, y)
        }
    });
    let comparison = compare(&a, &b);
    let pixels = (width * height) as usize;
    let b_to_a = comparison.b_to_a.all;
    assert_eq!(b_to_a.counted, pixels);
    assert_eq!(b_to_a.unseen, 0);
    assert!((b_to_a.max_px - 40.0).abs() < 1e-4, "{b_to_a:?}");
    assert_eq!(b_to_a.over_1px_fraction, 64.0 / pixels as f64);
    assert!((b_to_a.mean_px - 64.0 * 40.0 / pixels as f64).abs() < 1e-4);
    let a_to_b = comparison.a_to_b.all;
    assert_eq!(a_to_b.unseen, 64, "{a_to_b:?}");
    // The unseen points are measured to the nearest point B shows (the block's border, 1-4 px).
    assert!(a_to_b.max_px >= 1.0 && a_to_b.max_px <= 4.5, "{a_to_b:?}");
    // p99 of 3,072 pixels is the 3,042nd smallest: the 64 over it decide it, and it is not zero.
    assert!(b_to_a.p99_px > 39.0, "{b_to_a:?}");
    // Pooled, the block's pixels count in both directions.
    assert_eq!(comparison.both.all.counted, 2 * pixels);
    assert_eq!(comparison.both.all.unseen, 64);
}
