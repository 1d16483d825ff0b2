//! The region of the ground that frames some evaluation events: what `eval --events` suggests
//! (`--extent`) with each of its worst moments, and what `plot --events` shows of a time window.
//! One rule for both, so that the suggested window plotted without `--extent` shows the same
//! region as with it.

/// Metres kept around the outermost events, on every side.
pub const AROUND_M: f64 = 6.0;

/// Smallest side of the region, metres (a lone event is shown with its neighbourhood).
pub const MIN_SIDE_M: f64 = 20.0;

/// The region `(x0, x1, y0, y1)` (metres) around the finite `points`: their bounding box with
/// [`AROUND_M`] on every side, widened about its centre to at least [`MIN_SIDE_M`] on each axis,
/// and rounded outward to whole metres (the form `plot --extent` is given). `None` without a
/// finite point.
pub fn frame_points(points: impl IntoIterator<Item = (f64, f64)>) -> Option<(f64, f64, f64, f64)> {
    let mut bbox: Option<(f64, f64, f64, f64)> = None;
    for (x, y) in points {
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        bbox = Some(match bbox {
            None => (x, x, y, y),
            Some((a, b, c, d)) => (a.min(x), b.max(x), c.min(y), d.max(y)),
        });
    }
    let (x0, x1, y0, y1) = bbox?;
    let side = |lo: f64, hi: f64| {
        let (c, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0 + AROUND_M);
        let half = half.max(MIN_SIDE_M / 2.0);
        ((c - half).floor(), (c + half).ceil())
    };
    let ((x0, x1), (y0, y1)) = (side(x0, x1), side(y0, y1));
    Some((x0, x1, y0, y1))
}

/// [`frame_points`] of the events at `(seconds, (x, y))` whose time lies in `[from_s, to_s]`
/// (with half a microsecond of slack, as `plot` selects frames).
pub fn frame_window(
    events: impl IntoIterator<Item = (f64, (f64, f64))>,
    from_s: f64,
    to_s: f64,
) -> Option<(f64, f64, f64, f64)> {
    const EPS: f64 = 5e-7;
    frame_points(
        events
            .into_iter()
            .filter(|(t, _)| *t >= from_s - EPS && *t <= to_s + EPS)
            .map(|e| e.1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_every_point_with_room_around() {
        assert_eq!(frame_points([]), None);
        assert_eq!(frame_points([(f64::NAN, 1.0)]), None);
        // A lone event: 20 m square about it, whole metres.
        assert_eq!(frame_points([(10.4, -3.0)]), Some((0.0, 21.0, -13.0, 7.0)));
        // Far apart: each outermost event has 6 m around it.
        let pts = [(0.0, 0.0), (100.0, 5.0), (f64::INFINITY, 0.0)];
        let (x0, x1, y0, y1) = frame_points(pts).unwrap();
        assert_eq!((x0, x1), (-6.0, 106.0));
        assert!(y0 <= -6.0 && y1 >= 11.0 && y1 - y0 >= MIN_SIDE_M);
        // A window keeps the events of its span, ends included.
        let timed = [(1.0, (0.0, 0.0)), (3.0, (100.0, 0.0)), (5.0, (500.0, 0.0))];
        let w = frame_window(timed, 1.0, 3.0).unwrap();
        assert_eq!((w.0, w.1), (-6.0, 106.0));
        assert_eq!(frame_window(timed, 3.5, 4.5), None);
    }
}
