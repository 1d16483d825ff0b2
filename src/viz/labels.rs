//! Placing the labels of a plot panel, in picture pixels. Each label, in the order given (most
//! important first), tries places around what it names at growing distances (touching it, then
//! one step out, two, ...; above, below, right, left and the corners) and takes the cheapest
//! place that is inside the plotting area and covers no label placed before and no mark (the
//! event rings). A strict label (an id's) also covers no box (the bold last boxes, the small
//! marks); another (an event's) may, at a cost. The cost prefers places that cover few boxes and
//! drawn lines (an occupancy grid of the outlines and paths), are near, and whose leader line
//! crosses few labels and marks (and that cover few leader lines). A label with no such place is
//! left out: labels never overlap.

use super::plot_layout::PxRect;

/// A label to place.
#[derive(Debug, Clone)]
pub struct LabelRequest {
    /// Width and height of its box (text and backing), pixels.
    pub size: (f64, f64),
    /// What it names (pixels); the label stays outside it.
    pub target: PxRect,
    /// How many steps out it may go (a step is a label height).
    pub steps: usize,
    /// Whether it must keep clear of the boxes (else covering one costs).
    pub strict: bool,
}

/// What labels keep clear of.
#[derive(Debug, Clone, Default)]
pub struct Obstacles {
    /// Never covered by a label (the event rings).
    pub marks: Vec<PxRect>,
    /// Never covered by a strict label, covered by another at a cost (the bold last boxes).
    pub boxes: Vec<PxRect>,
}

/// A placed label: its box and the leader line `[at the label, at the target]`, if not touching.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// The label's box.
    pub rect: PxRect,
    /// Leader line.
    pub leader: Option<[(f64, f64); 2]>,
}

/// Which cells of a grid over the plotting area hold drawn lines, with a summed-area table so
/// that the share of a rectangle's cells that hold lines costs four lookups.
pub struct Occupancy {
    area: PxRect,
    cell: f64,
    cols: usize,
    rows: usize,
    /// `(cols + 1) * (rows + 1)` prefix sums.
    sums: Vec<u32>,
}

/// An [`Occupancy`] being filled segment by segment, so that the segments need not be held.
pub struct OccupancyGrid {
    area: PxRect,
    cell: f64,
    cols: usize,
    rows: usize,
    hit: Vec<bool>,
}

impl OccupancyGrid {
    /// An empty grid of `cell`-pixel cells over `area`.
    pub fn new(area: PxRect, cell: f64) -> OccupancyGrid {
        let cols = (area.width() / cell).ceil().max(1.0) as usize;
        let rows = (area.height() / cell).ceil().max(1.0) as usize;
        OccupancyGrid {
            area,
            cell,
            cols,
            rows,
            hit: vec![false; cols * rows],
        }
    }

    /// Marks the cells the segment from `a` to `b` crosses (sampled every half cell).
    pub fn mark(&mut self, a: (f64, f64), b: (f64, f64)) {
        let (area, cell, cols, rows) = (self.area, self.cell, self.cols, self.rows);
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) / (cell / 2.0)).ceil() as usize;
        for i in 0..=n.min(100_000) {
            let t = if n == 0 { 0.0 } else { i as f64 / n as f64 };
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            let (c, r) = ((x - area.x0) / cell, (y - area.y0) / cell);
            if c >= 0.0 && r >= 0.0 && (c as usize) < cols && (r as usize) < rows {
                self.hit[r as usize * cols + c as usize] = true;
            }
        }
    }

    /// The finished grid, with its summed-area table.
    pub fn finish(self) -> Occupancy {
        let (cols, rows, hit) = (self.cols, self.rows, self.hit);
        let mut sums = vec![0u32; (cols + 1) * (rows + 1)];
        for r in 0..rows {
            for c in 0..cols {
                let v = u32::from(hit[r * cols + c]);
                sums[(r + 1) * (cols + 1) + c + 1] =
                    v + sums[r * (cols + 1) + c + 1] + sums[(r + 1) * (cols + 1) + c]
                        - sums[r * (cols + 1) + c];
            }
        }
        Occupancy {
            area: self.area,
            cell: self.cell,
            cols,
            rows,
            sums,
        }
    }
}

impl Occupancy {
    /// The grid of `cell`-pixel cells over `area` with the segments drawn in it.
    pub fn new(area: PxRect, cell: f64, segments: &[[(f64, f64); 2]]) -> Occupancy {
        let mut grid = OccupancyGrid::new(area, cell);
        for &[a, b] in segments {
            grid.mark(a, b);
        }
        grid.finish()
    }

    /// Share (0 to 1) of the cells under `r` that hold lines.
    pub fn share(&self, r: &PxRect) -> f64 {
        let idx =
            |v: f64, lo: f64, n: usize| (((v - lo) / self.cell).floor().max(0.0) as usize).min(n);
        let (c0, c1) = (
            idx(r.x0, self.area.x0, self.cols),
            idx(r.x1, self.area.x0, self.cols),
        );
        let (r0, r1) = (
            idx(r.y0, self.area.y0, self.rows),
            idx(r.y1, self.area.y0, self.rows),
        );
        if c1 <= c0 || r1 <= r0 {
            return 0.0;
        }
        let s = |r: usize, c: usize| i64::from(self.sums[r * (self.cols + 1) + c]);
        let n = s(r1, c1) - s(r0, c1) - s(r1, c0) + s(r0, c0);
        n as f64 / ((c1 - c0) * (r1 - r0)) as f64
    }
}

/// Candidate boxes for a `w` x `h` label `d` pixels off `t`, with a preference cost each:
/// above (left-aligned, centred, right-aligned), below, then 16 directions around (above
/// first), each box the nearest one in that direction that keeps `d` from `t`.
fn around(t: &PxRect, (w, h): (f64, f64), d: f64) -> Vec<(PxRect, f64)> {
    let (cx, cy) = t.center();
    let at = |x0: f64, y0: f64| PxRect {
        x0,
        x1: x0 + w,
        y0,
        y1: y0 + h,
    };
    let (above, below) = (t.y0 - d - h, t.y1 + d);
    let mut out = vec![
        (at(t.x0, above), 0.0),
        (at(cx - w / 2.0, above), 0.05),
        (at(t.x1 - w, above), 0.1),
        (at(t.x0, below), 0.2),
        (at(cx - w / 2.0, below), 0.25),
        (at(t.x1 - w, below), 0.3),
    ];
    let (a, b) = (
        t.width() / 2.0 + d + w / 2.0,
        t.height() / 2.0 + d + h / 2.0,
    );
    for i in 0..16 {
        // From straight up, alternating right and left, down to straight down.
        let step = f64::from((i + 1) / 2) * std::f64::consts::PI / 8.0;
        let angle = if i % 2 == 0 { step } else { -step };
        let (ux, uy) = (angle.sin(), -angle.cos());
        let s = match (ux.abs() > 1e-9, uy.abs() > 1e-9) {
            (true, true) => (a / ux.abs()).min(b / uy.abs()),
            (true, false) => a / ux.abs(),
            _ => b / uy.abs(),
        };
        let (mx, my) = (cx + ux * s, cy + uy * s);
        out.push((at(mx - w / 2.0, my - h / 2.0), 0.1 + 0.04 * f64::from(i)));
    }
    out
}

/// The leader line from `label` to `target`: from the label's point nearest the target's
/// centre to the target's point nearest that; `None` when shorter than `touch` pixels.
fn leader(label: &PxRect, target: &PxRect, touch: f64) -> Option<[(f64, f64); 2]> {
    let from = label.nearest(target.center());
    let to = target.nearest(from);
    let len = (from.0 - to.0).hypot(from.1 - to.1);
    (len > touch).then_some([from, to])
}

/// What a new label must keep clear of.
struct Taken<'a> {
    bounds: PxRect,
    obstacles: &'a Obstacles,
    labels: Vec<PxRect>,
    leaders: Vec<[(f64, f64); 2]>,
}

impl Taken<'_> {
    /// The extra cost of a label at `r` with leader `line` naming `target`, `None` when the
    /// place is not allowed.
    fn cost(
        &self,
        r: &PxRect,
        line: Option<[(f64, f64); 2]>,
        target: &PxRect,
        strict: bool,
    ) -> Option<f64> {
        if !self.bounds.contains_rect(r) {
            return None;
        }
        let hit = |o: &PxRect| o.overlaps(r);
        if self.labels.iter().any(hit) || self.obstacles.marks.iter().any(hit) {
            return None;
        }
        let boxes = self.obstacles.boxes.iter().filter(|o| hit(o)).count();
        if strict && boxes > 0 {
            return None;
        }
        // A leader line under a label, or through one, is allowed at a cost.
        let mut cost = 1.5 * boxes as f64
            + 2.0
                * self
                    .leaders
                    .iter()
                    .filter(|[a, b]| r.crossed_by(*a, *b))
                    .count() as f64;
        if let Some([a, b]) = line {
            let crossed = |o: &&PxRect| *o != target && o.crossed_by(a, b);
            cost += 2.0 * self.labels.iter().filter(crossed).count() as f64
                + (self.obstacles.marks.iter().filter(crossed).count() as f64)
                + 0.3 * self.obstacles.boxes.iter().filter(crossed).count() as f64;
        }
        Some(cost)
    }
}

/// Places the labels in order; `None` for one left out. `lines` is the occupancy of what is
/// drawn, `bounds` the plotting area.
pub fn place_labels(
    requests: &[LabelRequest],
    bounds: PxRect,
    obstacles: &Obstacles,
    lines: &Occupancy,
) -> Vec<Option<Placed>> {
    let mut taken = Taken {
        bounds,
        obstacles,
        labels: Vec::new(),
        leaders: Vec::new(),
    };
    let mut out = Vec::with_capacity(requests.len());
    for req in requests {
        let (w, h) = req.size;
        let gap = 2.0;
        let mut best: Option<(f64, Placed)> = None;
        for step in 0..=req.steps {
            let d = gap + step as f64 * h;
            // A nearer step always wins over a farther one that covers no more.
            if best.as_ref().is_some_and(|(c, _)| *c <= step as f64 * 0.8) {
                break;
            }
            for (rect, pref) in around(&req.target, (w, h), d) {
                let line = leader(&rect, &req.target, gap + 1.0);
                let Some(extra) = taken.cost(&rect, line, &req.target, req.strict) else {
                    continue;
                };
                let cost = 3.0 * lines.share(&rect) + step as f64 * 0.8 + pref + extra;
                if best.as_ref().is_none_or(|(c, _)| cost < *c) {
                    best = Some((cost, Placed { rect, leader: line }));
                }
            }
        }
        if let Some((_, p)) = best {
            taken.labels.push(p.rect);
            taken.leaders.extend(p.leader);
        }
        out.push(best.map(|(_, p)| p));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: f64, x1: f64, y0: f64, y1: f64) -> PxRect {
        PxRect { x0, x1, y0, y1 }
    }

    #[test]
    fn labels_of_neighbouring_boxes_do_not_overlap() {
        let bounds = rect(0.0, 400.0, 0.0, 300.0);
        // Twelve boxes 6 px apart in a row: their natural spots (above each) all collide.
        let boxes: Vec<PxRect> = (0..12)
            .map(|i| {
                let x = 150.0 + 6.0 * f64::from(i);
                rect(x, x + 4.0, 150.0, 154.0)
            })
            .collect();
        let requests: Vec<LabelRequest> = boxes
            .iter()
            .map(|b| LabelRequest {
                size: (80.0, 15.0),
                target: *b,
                steps: 6,
                strict: true,
            })
            .collect();
        let lines = Occupancy::new(bounds, 2.0, &[]);
        let obstacles = Obstacles {
            marks: Vec::new(),
            boxes: boxes.clone(),
        };
        let placed = place_labels(&requests, bounds, &obstacles, &lines);
        let rects: Vec<PxRect> = placed.iter().flatten().map(|p| p.rect).collect();
        assert!(rects.len() >= 10, "{} of 12 placed", rects.len());
        for (i, p) in placed.iter().flatten().enumerate() {
            assert!(bounds.contains_rect(&p.rect));
            assert!(boxes.iter().all(|b| !b.overlaps(&p.rect)), "covers a box");
            for (j, q) in placed.iter().flatten().enumerate().take(i) {
                assert!(!p.rect.overlaps(&q.rect), "{i} and {j}");
            }
            // A label away from its box has a leader line from its edge to the box's edge.
            if let Some([a, b]) = p.leader {
                let edge = |r: &PxRect, q: (f64, f64)| r.grown(0.01).contains(q);
                assert!(edge(&p.rect, a) && edge(&requests[i].target, b));
            }
        }
        // The first takes the best spot: just above its box, touching it.
        let first = placed[0].unwrap();
        assert_eq!(first.rect.y1, 148.0);
        assert!(first.leader.is_none());
    }

    #[test]
    fn a_label_with_no_room_is_left_out() {
        let bounds = rect(0.0, 100.0, 0.0, 100.0);
        let req = LabelRequest {
            size: (150.0, 15.0),
            target: rect(40.0, 60.0, 40.0, 60.0),
            steps: 4,
            strict: false,
        };
        let lines = Occupancy::new(bounds, 2.0, &[]);
        let none = Obstacles::default();
        assert_eq!(place_labels(&[req], bounds, &none, &lines), vec![None]);
    }

    #[test]
    fn labels_prefer_empty_ground() {
        let bounds = rect(0.0, 200.0, 0.0, 200.0);
        // Lines fill the band above the box; below is empty.
        let segments: Vec<[(f64, f64); 2]> = (0..20)
            .map(|i| {
                let y = 60.0 + 2.0 * f64::from(i);
                [(0.0, y), (200.0, y)]
            })
            .collect();
        let lines = Occupancy::new(bounds, 2.0, &segments);
        assert!(lines.share(&rect(0.0, 200.0, 60.0, 98.0)) > 0.9);
        assert_eq!(lines.share(&rect(0.0, 200.0, 120.0, 200.0)), 0.0);
        let req = LabelRequest {
            size: (40.0, 15.0),
            target: rect(90.0, 110.0, 100.0, 110.0),
            steps: 4,
            strict: false,
        };
        let p = place_labels(&[req], bounds, &Obstacles::default(), &lines)[0].unwrap();
        assert!(p.rect.y0 >= 110.0, "{p:?}");
    }
}
