//! The running executable's identity, for the manifest's fingerprint: a rebuilt tool may trace
//! differently, so its frames are not taken for this one's.
//!
//! Where the executable is an ELF file with a GNU build ID (the linker's hash of the linked
//! file, which GNU ld, gold, lld and mold write when asked, and Debian's and Fedora's compilers
//! ask by default), that note is the identity: a few small reads. Elsewhere the file's SHA-256
//! is: with debug information the release executable is about 72 MB, and hashing it took about
//! 12% of a one-frame render of the default pipeline.

use sha2::{Digest, Sha256};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;
use std::sync::OnceLock;

/// The identity of the running executable: `build-id:<hex>`, `sha256:<hex>` or `unknown`.
pub fn tool_id() -> &'static str {
    static ID: OnceLock<String> = OnceLock::new();
    ID.get_or_init(|| {
        std::env::current_exe()
            .ok()
            .and_then(|exe| identify(&exe))
            .unwrap_or_else(|| "unknown".into())
    })
}

fn identify(exe: &Path) -> Option<String> {
    let mut file = std::fs::File::open(exe).ok()?;
    if let Some(id) = gnu_build_id(&mut file) {
        return Some(format!("build-id:{}", hex(&id)));
    }
    file.seek(SeekFrom::Start(0)).ok()?;
    sha256_of(file).ok().map(|h| format!("sha256:{h}"))
}

/// The SHA-256 of everything `reader` yields, read in pieces (no copy of the whole file).
pub fn sha256_of(mut reader: impl Read) -> std::io::Result<String> {
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        match reader.read(&mut buf) {
            Ok(0) => return Ok(hex(&h.finalize())),
            Ok(n) => h.update(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// ELF (System V gABI, "Program Header" and "Note Section"): the 64-bit little-endian layout.
const ELF_MAGIC: [u8; 4] = *b"\x7fELF";
const ELFCLASS64: u8 = 2;
const ELFDATA2LSB: u8 = 1;
const PT_NOTE: u32 = 4;
const PROGRAM_HEADER_SIZE: usize = 56;
/// The note type of a build ID under the owner "GNU" (binutils' `elf/common.h`).
const NT_GNU_BUILD_ID: u32 = 3;
/// Bounds on what is read: executables have about a dozen program headers and a few notes.
const MAX_PROGRAM_HEADERS: usize = 256;
const MAX_NOTE_BYTES: u64 = 1 << 16;

/// The descriptor of the first GNU build-ID note of a 64-bit little-endian ELF file's note
/// segments, or `None` (another format, no such note, or a file that does not hold together).
pub fn gnu_build_id(file: &mut (impl Read + Seek)) -> Option<Vec<u8>> {
    let header = read_at(file, 0, 64)?;
    if header[..4] != ELF_MAGIC || header[4] != ELFCLASS64 || header[5] != ELFDATA2LSB {
        return None;
    }
    let phoff = u64_at(&header, 0x20)?;
    let phentsize = u16_at(&header, 0x36)? as usize;
    let phnum = u16_at(&header, 0x38)? as usize;
    if phentsize != PROGRAM_HEADER_SIZE || phnum > MAX_PROGRAM_HEADERS {
        return None;
    }
    let headers = read_at(file, phoff, phnum * phentsize)?;
    headers.chunks_exact(phentsize).find_map(|ph| {
        if u32_at(ph, 0)? != PT_NOTE {
            return None;
        }
        let (offset, size, align) = (u64_at(ph, 8)?, u64_at(ph, 32)?, u64_at(ph, 48)?);
        if size > MAX_NOTE_BYTES {
            return None;
        }
        let notes = read_at(file, offset, size as usize)?;
        build_id_note(&notes, if align == 8 { 8 } else { 4 })
    })
}

/// Walks one note segment: each note is name size, descriptor size and type (4 bytes each),
/// then the name, and the descriptor and the next note each at the segment's alignment.
fn build_id_note(notes: &[u8], align: usize) -> Option<Vec<u8>> {
    let aligned = |n: usize| n.div_ceil(align) * align;
    let mut at = 0;
    while at + 12 <= notes.len() {
        let name_size = u32_at(notes, at)? as usize;
        let desc_size = u32_at(notes, at + 4)? as usize;
        let kind = u32_at(notes, at + 8)?;
        let name_at = at + 12;
        let desc_at = aligned(name_at.checked_add(name_size)?);
        let end = aligned(desc_at.checked_add(desc_size)?);
        let name = notes.get(name_at..name_at.checked_add(name_size)?)?;
        let desc = notes.get(desc_at..desc_at.checked_add(desc_size)?)?;
        if kind == NT_GNU_BUILD_ID && name == b"GNU\0" && !desc.is_empty() {
            return Some(desc.to_vec());
        }
        at = end;
    }
    None
}

fn read_at(file: &mut (impl Read + Seek), offset: u64, len: usize) -> Option<Vec<u8>> {
    file.seek(SeekFrom::Start(offset)).ok()?;
    let mut buf = vec![0u8; len];
    file.read_exact(&mut buf).ok()?;
    Some(buf)
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// A minimal ELF file: the header, one PT_LOAD and one PT_NOTE header, then `notes`.
    fn elf_with_notes(notes: &[u8], align: u64) -> Vec<u8> {
        let mut f = vec![0u8; 64];
        f[..4].copy_from_slice(&ELF_MAGIC);
        f[4] = ELFCLASS64;
        f[5] = ELFDATA2LSB;
        f[0x20..0x28].copy_from_slice(&64u64.to_le_bytes());
        f[0x36..0x38].copy_from_slice(&(PROGRAM_HEADER_SIZE as u16).to_le_bytes());
        f[0x38..0x3a].copy_from_slice(&2u16.to_le_bytes());
        let notes_at = 64 + 2 * PROGRAM_HEADER_SIZE as u64;
        for (kind, offset, size) in [(1u32, 0u64, 0u64), (PT_NOTE, notes_at, notes.len() as u64)] {
            let mut ph = vec![0u8; PROGRAM_HEADER_SIZE];
            ph[..4].copy_from_slice(&kind.to_le_bytes());
            ph[8..16].copy_from_slice(&offset.to_le_bytes());
            ph[32..40].copy_from_slice(&size.to_le_bytes());
            ph[48..56].copy_from_slice(&align.to_le_bytes());
            f.extend(ph);
        }
        f.extend(notes);
        f
    }

    fn note(name: &[u8], kind: u32, desc: &[u8], align: usize) -> Vec<u8> {
        let mut n = Vec::new();
        n.extend((name.len() as u32).to_le_bytes());
        n.extend((desc.len() as u32).to_le_bytes());
        n.extend(kind.to_le_bytes());
        for part in [name, desc] {
            n.extend(part);
            n.resize(n.len().div_ceil(align) * align, 0);
        }
        n
    }

    #[test]
    fn finds_the_build_id_after_other_notes_at_either_alignment() {
        let id = [0xa8, 0xc7, 0x01, 0x23, 0x45];
        for align in [4usize, 8] {
            let mut notes = note(b"GNU\0", 5, &[1, 2, 3, 4, 5, 6, 7, 8, 9], align);
            notes.extend(note(b"FDO\0", NT_GNU_BUILD_ID, &[9; 7], align));
            notes.extend(note(b"GNU\0", NT_GNU_BUILD_ID, &id, align));
            let elf = elf_with_notes(&notes, align as u64);
            assert_eq!(
                gnu_build_id(&mut Cursor::new(elf)),
                Some(id.to_vec()),
                "{align}"
            );
        }
    }

    #[test]
    fn a_file_that_does_not_hold_together_has_no_build_id() {
        let id = note(b"GNU\0", NT_GNU_BUILD_ID, &[7; 20], 4);
        let good = elf_with_notes(&id, 4);
        assert!(gnu_build_id(&mut Cursor::new(good.clone())).is_some());
        // Cut anywhere: the note, the program headers, the ELF header.
        for len in [good.len() - 1, 64 + 60, 40, 0] {
            assert_eq!(gnu_build_id(&mut Cursor::new(good[..len].to_vec())), None);
        }
        // A descriptor size that runs past the segment.
        let mut lying = id.clone();
        lying[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(
            gnu_build_id(&mut Cursor::new(elf_with_notes(&lying, 4))),
            None
        );
        // Not ELF, or 32-bit ELF.
        let mut other = good.clone();
        other[0] = b'M';
        assert_eq!(gnu_build_id(&mut Cursor::new(other)), None);
        let mut elf32 = good;
        elf32[4] = 1;
        assert_eq!(gnu_build_id(&mut Cursor::new(elf32)), None);
    }

    #[test]
    fn streamed_hash_is_the_hash_of_the_bytes() {
        let bytes: Vec<u8> = (0..200_000u32).map(|i| (i * 7 % 251) as u8).collect();
        assert_eq!(
            sha256_of(Cursor::new(&bytes)).unwrap(),
            hex(&Sha256::digest(&bytes))
        );
    }

    #[test]
    fn the_running_tool_has_an_identity() {
        let id = tool_id();
        assert!(
            id.starts_with("build-id:") || id.starts_with("sha256:"),
            "{id}"
        );
        assert_eq!(
            identify(&std::env::current_exe().unwrap()).as_deref(),
            Some(id)
        );
    }
}
