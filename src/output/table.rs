//! CSV tables (the frame log, benchmark tables), quoted by the `csv` crate's rules (RFC 4180:
//! a field holding a comma, a quote or a line break is quoted), so that any value a user can
//! sweep or name survives a round trip. Files are written atomically.

use super::write_atomic;
use crate::error::{Error, Result};
use std::path::Path;

/// Writes a header and rows as a CSV file.
pub fn write_csv<R: AsRef<[String]>>(path: &Path, header: &[&str], rows: &[R]) -> Result<()> {
    write_atomic(path, |w| {
        let mut out = csv::Writer::from_writer(w);
        out.write_record(header)?;
        for r in rows {
            out.write_record(r.as_ref())?;
        }
        out.flush()
    })
}

/// One CSV record as a line of text (without the line break), for tables printed as they grow.
pub fn csv_line(fields: &[String]) -> String {
    let mut out = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    out.write_record(fields)
        .expect("writing CSV into memory cannot fail");
    let bytes = out
        .into_inner()
        .expect("flushing CSV into memory cannot fail");
    String::from_utf8_lossy(&bytes)
        .trim_end_matches('\n')
        .to_string()
}

/// Reads a CSV file: its header and its rows.
pub fn read_csv(path: &Path, what: &str) -> Result<(Vec<String>, Vec<Vec<String>>)> {
    let cannot = |e: csv::Error| Error::input(path, format!("cannot read {what}: {e}"));
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .from_path(path)
        .map_err(cannot)?;
    let header = reader
        .headers()
        .map_err(cannot)?
        .iter()
        .map(str::to_string)
        .collect();
    let rows = reader
        .records()
        .map(|r| {
            r.map(|rec| rec.iter().map(str::to_string).collect())
                .map_err(|e| Error::input(path, format!("{what}: {e}")))
        })
        .collect::<Result<_>>()?;
    Ok((header, rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_with_commas_and_quotes_survive_a_round_trip() {
        let path = std::env::temp_dir().join(format!("table-{}.csv", std::process::id()));
        let rows = vec![vec![
            "[0.1,0.2]".to_string(),
            "say \"hi\"".to_string(),
            String::new(),
        ]];
        write_csv(&path, &["a", "b", "c"], &rows).unwrap();
        let (header, back) = read_csv(&path, "table").unwrap();
        assert_eq!(
            (header, back),
            (vec!["a".into(), "b".into(), "c".into()], rows.clone())
        );
        std::fs::remove_file(&path).unwrap();
        assert_eq!(csv_line(&rows[0]), "\"[0.1,0.2]\",\"say \"\"hi\"\"\",");
    }
}
