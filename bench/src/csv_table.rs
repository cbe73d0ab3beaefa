//! The measurement scripts' CSV tables (plain comma-separated values with
//! a header line, no quoting), read by column name for the plotting
//! examples; errors name the file, the line and the column.

use std::path::{Path, PathBuf};

/// A CSV file read whole: its header and its rows of fields.
#[derive(Debug, Clone)]
pub struct CsvTable {
    path: PathBuf,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl CsvTable {
    /// Reads `path`; an error if it cannot be read or has no header line.
    pub fn read(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut lines = text.lines();
        let header = lines
            .next()
            .ok_or_else(|| format!("{}: empty", path.display()))?
            .split(',')
            .map(str::to_string)
            .collect();
        let rows = lines
            .filter(|l| !l.is_empty())
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        Ok(Self {
            path: path.to_path_buf(),
            header,
            rows,
        })
    }

    /// The rows below the header.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are no rows below the header.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The index of the column `name`.
    pub fn column(&self, name: &str) -> Result<usize, String> {
        self.header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column {name}", self.path.display()))
    }

    /// The field of `row` in `column` ("" where the row is short).
    pub fn text(&self, row: usize, column: usize) -> &str {
        self.rows[row].get(column).map_or("", String::as_str)
    }

    /// The field of `row` in `column` as a number (a leading `+` allowed).
    pub fn number(&self, row: usize, column: usize) -> Result<f64, String> {
        self.text(row, column)
            .trim_start_matches('+')
            .parse()
            .map_err(|_| {
                format!(
                    "{}: line {}: no number in column {}",
                    self.path.display(),
                    row + 2,
                    self.header.get(column).map_or("?", String::as_str)
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_found_by_name_and_bad_fields_name_their_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("t.csv");
        std::fs::write(&path, "capture,difference_db\nstatue,+0.181\ncup,x\n").expect("write");
        let t = CsvTable::read(&path).expect("read");
        assert_eq!(t.len(), 2);
        let d = t.column("difference_db").expect("column");
        assert_eq!(t.text(0, t.column("capture").expect("column")), "statue");
        assert_eq!(t.number(0, d), Ok(0.181));
        let err = t.number(1, d).expect_err("not a number");
        assert!(
            err.contains("line 3") && err.contains("difference_db"),
            "{err}"
        );
        assert!(
            t.column("psnr")
                .expect_err("absent")
                .contains("no column psnr")
        );
        let empty = dir.path().join("e.csv");
        std::fs::write(&empty, "").expect("write");
        assert!(CsvTable::read(&empty).expect_err("empty").contains("empty"));
    }
}
