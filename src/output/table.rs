//! CSV tables (the frame log, benchmark tables), quoted by the `csv` crate's rules (RFC 4180:
//! a field holding a comma, a quote or a line break is quoted), so that any value a user can
//! sweep or name survives a round trip. Files are written atomically.

use super::{temporary_beside, write_atomic};
use crate::error::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

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

/// A CSV file written row by row while a run goes on, so that memory stays flat however many
/// rows a run makes. Rows go into a temporary sibling that `finish` renames into place; dropped
/// unfinished (an error), the temporary is removed, so no half-written table is ever left.
pub struct CsvStream {
    path: PathBuf,
    tmp: PathBuf,
    out: Option<csv::Writer<BufWriter<File>>>,
}

impl CsvStream {
    pub fn create(path: &Path, header: &[&str]) -> Result<CsvStream> {
        let tmp = temporary_beside(path)?;
        let file = File::create(&tmp).map_err(|e| Error::io(path, e))?;
        let mut stream = CsvStream {
            path: path.to_path_buf(),
            tmp,
            out: Some(csv::Writer::from_writer(BufWriter::new(file))),
        };
        stream.write(|out| out.write_record(header))?;
        Ok(stream)
    }

    fn write(
        &mut self,
        f: impl FnOnce(&mut csv::Writer<BufWriter<File>>) -> csv::Result<()>,
    ) -> Result<()> {
        let out = self
            .out
            .as_mut()
            .expect("a CsvStream is written only before finish");
        f(out)
            .and_then(|()| out.flush().map_err(csv::Error::from))
            .map_err(|e| Error::io(&self.path, std::io::Error::other(e)))
    }

    /// Appends rows and hands them to the operating system (a crash of this process keeps them).
    pub fn append<R: AsRef<[String]>>(&mut self, rows: &[R]) -> Result<()> {
        self.write(|out| rows.iter().try_for_each(|r| out.write_record(r.as_ref())))
    }

    /// Syncs the rows to disk and renames the table into place.
    pub fn finish(mut self) -> Result<()> {
        let out = self.out.take().expect("a CsvStream is finished once");
        let result = out
            .into_inner()
            .map_err(|e| e.into_error())
            .and_then(|mut w| {
                w.flush()?;
                w.get_ref().sync_all()
            })
            .and_then(|()| std::fs::rename(&self.tmp, &self.path));
        result.map_err(|e| {
            let _ = std::fs::remove_file(&self.tmp);
            Error::io(&self.path, e)
        })
    }
}

impl Drop for CsvStream {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
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
