//! The Munkres (Hungarian) algorithm in the classic six-step formulation, with the same scan
//! orders as the implementation the reference uses, so that ties between equally good
//! assignments are broken the same way.

/// The working buffers of [`Munkres::solve`], kept between calls (one assignment per frame).
#[derive(Debug, Default)]
pub(super) struct Munkres {
    /// Side of the padded square matrix.
    n: usize,
    /// The padded cost matrix, reduced in place.
    c: Vec<f64>,
    /// 1 = starred, 2 = primed.
    marked: Vec<u8>,
    row_cov: Vec<bool>,
    col_cov: Vec<bool>,
    path: Vec<(usize, usize)>,
}

impl Munkres {
    /// Solves `cost` (`rows x cols`, row-major; padded with zeros to a square) and writes the
    /// assigned `(row, col)` pairs in row order into `out`.
    pub(super) fn solve(
        &mut self,
        cost: &[f64],
        rows: usize,
        cols: usize,
        out: &mut Vec<(usize, usize)>,
    ) {
        out.clear();
        if rows == 0 || cols == 0 {
            return;
        }
        self.reset(cost, rows, cols);
        let n = self.n;
        let mut step = 3;
        loop {
            step = match step {
                3 => {
                    if self.cover_starred_columns() >= n {
                        break;
                    }
                    4
                }
                4 => self.prime_zeros(),
                5 => self.augment(),
                _ => self.adjust(),
            };
        }
        for i in 0..rows {
            for j in 0..cols {
                if self.marked[i * n + j] == 1 {
                    out.push((i, j));
                }
            }
        }
    }

    /// Pads the matrix, subtracts each row's minimum (step 1) and stars zeros with no starred
    /// zero in their row or column (step 2).
    fn reset(&mut self, cost: &[f64], rows: usize, cols: usize) {
        let n = rows.max(cols);
        self.n = n;
        self.c.clear();
        self.c.resize(n * n, 0.0);
        for i in 0..rows {
            self.c[i * n..i * n + cols].copy_from_slice(&cost[i * cols..(i + 1) * cols]);
        }
        self.marked.clear();
        self.marked.resize(n * n, 0);
        self.row_cov.clear();
        self.row_cov.resize(n, false);
        self.col_cov.clear();
        self.col_cov.resize(n, false);
        for i in 0..n {
            let row = &mut self.c[i * n..(i + 1) * n];
            let mut m = row[0];
            for &v in row.iter().skip(1) {
                if v < m {
                    m = v;
                }
            }
            for v in row.iter_mut() {
                *v -= m;
            }
        }
        for i in 0..n {
            for j in 0..n {
                if self.c[i * n + j] == 0.0 && !self.col_cov[j] && !self.row_cov[i] {
                    self.marked[i * n + j] = 1;
                    self.col_cov[j] = true;
                    self.row_cov[i] = true;
                }
            }
        }
        self.clear_covers();
    }

    fn clear_covers(&mut self) {
        self.row_cov.iter_mut().for_each(|v| *v = false);
        self.col_cov.iter_mut().for_each(|v| *v = false);
    }

    /// Step 3: covers the columns of starred zeros; returns their number.
    fn cover_starred_columns(&mut self) -> usize {
        let n = self.n;
        let mut count = 0;
        for i in 0..n {
            for j in 0..n {
                if self.marked[i * n + j] == 1 {
                    self.col_cov[j] = true;
                    count += 1;
                }
            }
        }
        count
    }

    /// Step 4: primes uncovered zeros (the first row with one, the last such zero in it) until
    /// one has no starred zero in its row (then step 5 from it) or none is left (step 6).
    fn prime_zeros(&mut self) -> usize {
        let n = self.n;
        loop {
            let mut found = None;
            for i in 0..n {
                for j in 0..n {
                    if self.c[i * n + j] == 0.0 && !self.row_cov[i] && !self.col_cov[j] {
                        found = Some((i, j));
                    }
                }
                if found.is_some() {
                    break;
                }
            }
            let Some((r, col)) = found else {
                return 6;
            };
            self.marked[r * n + col] = 2;
            match (0..n).find(|&j| self.marked[r * n + j] == 1) {
                Some(sc) => {
                    self.row_cov[r] = true;
                    self.col_cov[sc] = false;
                }
                None => {
                    self.path.clear();
                    self.path.push((r, col));
                    return 5;
                }
            }
        }
    }

    /// Step 5: the alternating path of primed and starred zeros from the last primed zero;
    /// flips it, clears covers and primes.
    fn augment(&mut self) -> usize {
        let n = self.n;
        loop {
            let col = self.path[self.path.len() - 1].1;
            let Some(r) = (0..n).find(|&i| self.marked[i * n + col] == 1) else {
                break;
            };
            self.path.push((r, col));
            let pc = (0..n).find(|&j| self.marked[r * n + j] == 2).unwrap_or(0);
            self.path.push((r, pc));
        }
        for &(i, j) in &self.path {
            let m = &mut self.marked[i * n + j];
            *m = if *m == 1 { 0 } else { 1 };
        }
        self.clear_covers();
        self.marked
            .iter_mut()
            .filter(|m| **m == 2)
            .for_each(|m| *m = 0);
        3
    }

    /// Step 6: adds the smallest uncovered value to covered rows and subtracts it from
    /// uncovered columns.
    fn adjust(&mut self) -> usize {
        let n = self.n;
        let mut minval = i64::MAX as f64;
        for i in 0..n {
            for j in 0..n {
                if !self.row_cov[i] && !self.col_cov[j] && minval > self.c[i * n + j] {
                    minval = self.c[i * n + j];
                }
            }
        }
        for i in 0..n {
            for j in 0..n {
                if self.row_cov[i] {
                    self.c[i * n + j] += minval;
                }
                if !self.col_cov[j] {
                    self.c[i * n + j] -= minval;
                }
            }
        }
        4
    }
}

/// [`Munkres::solve`] with fresh buffers: the assigned `(row, col)` pairs in row order.
#[cfg(test)]
pub(super) fn munkres(cost: &[f64], rows: usize, cols: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    Munkres::default().solve(cost, rows, cols, &mut out);
    out
}
