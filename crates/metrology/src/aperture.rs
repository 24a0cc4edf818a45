//! A map over a part's circular aperture on a square grid in the part's frame: what a
//! prediction, a registered measurement and a compensation share, and its CSV form (a sag grid
//! that a prescription's `[compensation]` loads back).

use optics::SagGrid;

/// `nodes × nodes` values (m), row 0 at +y, column 0 at −x (Zemax's grid layout), centred on
/// the part's axis, NaN outside the aperture or without data.
#[derive(Debug, Clone, PartialEq)]
pub struct ApertureMap {
    /// Nodes per side.
    pub nodes: usize,
    /// Node spacing, m.
    pub pitch_m: f64,
    /// Row-major values, m.
    pub values: Vec<f64>,
}

impl ApertureMap {
    /// `f(x, y)` at every node of a `nodes × nodes` grid spanning the aperture of radius
    /// `aperture_m` (m), NaN outside it.
    pub fn of(nodes: usize, aperture_m: f64, f: impl Fn(f64, f64) -> f64) -> Self {
        let pitch = 2.0 * aperture_m / (nodes - 1) as f64;
        let mut map = ApertureMap {
            nodes,
            pitch_m: pitch,
            values: Vec::new(),
        };
        map.values = (0..nodes * nodes)
            .map(|i| {
                let (x, y) = map.xy(i);
                if libm::hypot(x, y) <= aperture_m * (1.0 + 1e-12) {
                    f(x, y)
                } else {
                    f64::NAN
                }
            })
            .collect();
        map
    }

    /// Node `i`'s position in the part's frame, m.
    pub fn xy(&self, i: usize) -> (f64, f64) {
        let half = (self.nodes - 1) as f64 / 2.0;
        let (row, col) = (i / self.nodes, i % self.nodes);
        (
            (col as f64 - half) * self.pitch_m,
            (half - row as f64) * self.pitch_m,
        )
    }

    /// The value at `(x_m, y_m)` (m), bilinear between the four nodes around it (NaN beyond
    /// the grid or beside a node without a value).
    pub fn at(&self, x_m: f64, y_m: f64) -> f64 {
        let half = (self.nodes - 1) as f64 / 2.0;
        let (col, row) = (x_m / self.pitch_m + half, half - y_m / self.pitch_m);
        crate::map::bilinear(&self.values, self.nodes, self.nodes, col, row)
    }

    /// The nodes with a value: position (m) and value (m).
    pub fn points(&self) -> Vec<(f64, f64, f64)> {
        self.values
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(i, &v)| {
                let (x, y) = self.xy(i);
                (x, y, v)
            })
            .collect()
    }

    /// The map, a height toward the tool, as sag values (m, sag = −height) on every node:
    /// a node without a value takes the value of the nearest one inside along its radius, so
    /// a grid's interpolation has neighbours there.
    fn filled_sag_m(&self) -> Vec<f64> {
        let n = self.nodes;
        let half = (n - 1) as f64 / 2.0;
        (0..n * n)
            .map(|i| {
                let (row, col) = (i / n, i % n);
                let mut v = self.values[i];
                // Walk inward along the radius to a node with a value.
                let (x, y) = (col as f64 - half, half - row as f64);
                let mut f = 1.0;
                while !v.is_finite() && f > 0.0 {
                    f -= 1.0 / half;
                    let (c, r) = (
                        (x * f + half).round() as usize,
                        (half - y * f).round() as usize,
                    );
                    v = self.values[r.min(n - 1) * n + c.min(n - 1)];
                }
                if v.is_finite() {
                    -v
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The map as a sag grid (see [`ApertureMap::to_sag_csv`]).
    pub fn to_sag_grid(&self) -> SagGrid {
        SagGrid {
            pitch_m: [self.pitch_m; 2],
            columns: self.nodes,
            rows: self.nodes,
            sag_m: self.filled_sag_m(),
        }
    }

    /// The map, a height toward the tool, as a sag grid CSV in mm (sag = −height; `what`
    /// names it in the first line, with the layout and the pitch), nodes outside filled as
    /// [`ApertureMap::to_sag_grid`]'s.
    pub fn to_sag_csv(&self, what: &str) -> String {
        let mut s = format!(
            "# {what} as sag in mm, row 0 at +y, column 0 at -x, pitch {} mm\n",
            self.pitch_m * 1e3
        );
        for row in self.filled_sag_m().chunks(self.nodes) {
            let cells: Vec<String> = row.iter().map(|v| format!("{:.6e}", v * 1e3)).collect();
            s += &cells.join(",");
            s.push('\n');
        }
        s
    }
}
