//! Reading a CSV of the sweep back (plots, docs, tests).

/// A CSV written by `format` (points.csv, runs.csv), read back by column name (no quoting: cells never
/// contain commas).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Cells, row by row.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// Parses CSV text (first line the header); rows must have the header's width.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let mut lines = text.lines();
        let header: Vec<String> = lines
            .next()
            .ok_or("empty file")?
            .split(',')
            .map(str::to_string)
            .collect();
        let mut rows = Vec::new();
        for (i, l) in lines.enumerate() {
            let row: Vec<String> = l.split(',').map(str::to_string).collect();
            if row.len() != header.len() {
                return Err(format!(
                    "row {} has {} cells, the header {}",
                    i + 1,
                    row.len(),
                    header.len()
                ));
            }
            rows.push(row);
        }
        Ok(Self { header, rows })
    }

    /// Index of a column.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Cell `name` of row `row` as text.
    pub fn text(&self, row: usize, name: &str) -> Option<&str> {
        let c = self.column(name)?;
        self.rows.get(row).map(|r| r[c].as_str())
    }

    /// Cell `name` of row `row` as a number (None if empty or not a number).
    pub fn number(&self, row: usize, name: &str) -> Option<f64> {
        self.text(row, name)?.parse().ok()
    }

    /// The table without the timing columns (`wall_*`), as text: what must agree between
    /// thread counts, shardings and resumes.
    pub fn without_timing(&self) -> String {
        let keep: Vec<usize> = (0..self.header.len())
            .filter(|&c| !self.header[c].starts_with("wall_"))
            .collect();
        let line = |r: &[String]| {
            keep.iter()
                .map(|&c| r[c].as_str())
                .collect::<Vec<_>>()
                .join(",")
        };
        let mut s = line(&self.header);
        for r in &self.rows {
            s.push('\n');
            s.push_str(&line(r));
        }
        s
    }
}
