//! The one rule for relative paths that must stay inside their folder: output paths inside
//! `--out`, glTF buffer and image URIs inside the scene's folder.

use std::path::{Component, Path};

/// Why a path is not inside its folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outside {
    /// Absolute, or with a drive or root prefix.
    Absolute,
    /// A `..` climbs above the start.
    Escapes,
}

/// How many folders below its start a relative path ends (0: the start itself), or why it leaves.
pub fn depth_inside(path: &Path) -> Result<usize, Outside> {
    let mut depth = 0usize;
    for c in path.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => depth = depth.checked_sub(1).ok_or(Outside::Escapes)?,
            Component::RootDir | Component::Prefix(_) => return Err(Outside::Absolute),
        }
    }
    Ok(depth)
}

/// Reads a regular file. A folder, device or named pipe is refused before any read: `/dev/zero`
/// would fill memory and a pipe with no writer would block for ever.
pub fn read_regular(path: &Path) -> crate::Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|e| crate::Error::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a folder"
        } else {
            "a device or pipe"
        };
        return Err(crate::Error::input(
            path,
            format!("is {what}, not a regular file"),
        ));
    }
    std::fs::read(path).map_err(|e| crate::Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_dot_may_climb_back_but_never_above_the_start() {
        assert_eq!(depth_inside(Path::new("a/b/../c.png")), Ok(2));
        assert_eq!(depth_inside(Path::new("a/..")), Ok(0));
        assert_eq!(depth_inside(Path::new("a/../../x")), Err(Outside::Escapes));
        assert_eq!(depth_inside(Path::new("/x")), Err(Outside::Absolute));
    }
}
