//! Output path templates: `{frame}`, `{frame:0N}` (zero-padded to N digits) and `{eye}`. Paths are
//! relative to the output directory and may not leave it.

use crate::paths::{Outside, depth_inside};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq)]
enum Piece {
    Text(String),
    Frame { width: usize },
    Eye,
}

/// A parsed output path template.
#[derive(Clone, Debug, PartialEq)]
pub struct PathTemplate {
    pieces: Vec<Piece>,
}

impl PathTemplate {
    /// Parses and checks a template; the error says what is wrong with it.
    pub fn parse(s: &str) -> Result<PathTemplate, String> {
        if s.is_empty() {
            return Err("output path is empty".into());
        }
        let mut pieces = Vec::new();
        let mut rest = s;
        while let Some(open) = rest.find('{') {
            if open > 0 {
                pieces.push(Piece::Text(rest[..open].to_string()));
            }
            let close = rest[open..]
                .find('}')
                .ok_or_else(|| format!("unclosed '{{' in output path '{s}'"))?
                + open;
            let field = &rest[open + 1..close];
            pieces.push(match field {
                "frame" => Piece::Frame { width: 0 },
                "eye" => Piece::Eye,
                _ => match field.strip_prefix("frame:0").map(str::parse::<usize>) {
                    Some(Ok(width)) if width <= 12 => Piece::Frame { width },
                    _ => {
                        return Err(format!(
                            "unknown placeholder '{{{field}}}' in output path '{s}' (use {{frame}}, {{frame:04}} or {{eye}})"
                        ));
                    }
                },
            });
            rest = &rest[close + 1..];
        }
        if rest.contains('}') {
            return Err(format!("stray '}}' in output path '{s}'"));
        }
        if !rest.is_empty() {
            pieces.push(Piece::Text(rest.to_string()));
        }
        let t = PathTemplate { pieces };
        check_inside(&t.render(0, "left"))?;
        Ok(t)
    }

    pub fn has_frame(&self) -> bool {
        self.pieces.iter().any(|p| matches!(p, Piece::Frame { .. }))
    }

    pub fn has_eye(&self) -> bool {
        self.pieces.contains(&Piece::Eye)
    }

    pub fn render(&self, frame: u32, eye: &str) -> String {
        self.pieces
            .iter()
            .map(|p| match p {
                Piece::Text(t) => t.clone(),
                Piece::Frame { width } => format!("{frame:0width$}"),
                Piece::Eye => eye.to_string(),
            })
            .collect()
    }

    /// The file for a frame and eye under the output directory.
    pub fn path(&self, out_dir: &Path, frame: u32, eye: &str) -> PathBuf {
        out_dir.join(self.render(frame, eye))
    }
}

/// A relative path whose `..` never climbs above its start and that names a file.
fn check_inside(p: &str) -> Result<(), String> {
    match depth_inside(Path::new(p)) {
        Ok(0) => Err(format!("output path '{p}' names no file")),
        Ok(_) => Ok(()),
        Err(Outside::Escapes) => Err(format!("output path '{p}' escapes the output directory")),
        Err(Outside::Absolute) => Err(format!(
            "output path '{p}' is absolute; it must be relative to the output directory (--out)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_expand() {
        let t = PathTemplate::parse("out/{eye}/f{frame:04}_{frame}.png").unwrap();
        assert_eq!(t.render(7, "left"), "out/left/f0007_7.png");
        assert!(t.has_frame() && t.has_eye());
    }

    #[test]
    fn bad_templates_are_refused_with_a_reason() {
        for bad in [
            "",
            "/abs.png",
            "../x.png",
            "a/../../x.png",
            "{frames}.png",
            "{frame",
            "x}.png",
        ] {
            assert!(PathTemplate::parse(bad).is_err(), "{bad}");
        }
        assert!(PathTemplate::parse("a/../x.png").is_ok());
    }
}
