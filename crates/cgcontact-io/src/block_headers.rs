//! Checking the block headers of compressed XML VTK arrays before vtkio sees them.
//!
//! A compressed array starts with a header `[blocks, block size, last block size, compressed sizes...]`
//! and vtkio 0.7.0-rc2 allocates `block size × (blocks − 1) + last block size` bytes from it before it
//! decompresses anything. A corrupt header therefore asks for petabytes, and a failed allocation aborts
//! the process: no `catch_unwind` can turn that into an error. So we read each compressed array's
//! header first (inline `format="binary"` arrays and base64 appended data, raw appended data once
//! `raw_appended` has re-encoded it, which checks its headers too) and refuse sizes no real file can
//! have: deflate expands at most 1032 : 1 and LZ4 255 : 1, so an array may not decompress to more
//! than [`MAX_EXPANSION`] times the bytes that hold it ([`plausible_size`], the one test both use).

use base64::Engine as _;

use crate::ErrorKind;
use crate::raw_appended::{attribute, find, header_word};

/// Largest ratio of decompressed bytes to the compressed bytes (or the base64 text) holding them that
/// a valid array can have.
pub(crate) const MAX_EXPANSION: u128 = 1100;

/// Whether `claimed` decompressed bytes can come from `held` bytes of compressed data or its text:
/// at most [`MAX_EXPANSION`] times them, plus 64 KiB for the smallest arrays' headers.
pub(crate) fn plausible_size(claimed: u128, held: u128) -> bool {
    claimed <= MAX_EXPANSION.saturating_mul(held).saturating_add(1 << 16)
}

/// The compressed arrays of a file, as [`check`] found them: where each one's base64 text starts
/// (its header first), and how their header words are written.
#[derive(Debug, Default)]
pub(crate) struct Headers {
    starts: Vec<usize>,
    header_bytes: usize,
    little: bool,
}

impl Headers {
    /// `xml` with each header that gives its last block 0 bytes, and so says that block is a whole
    /// one (VTK's rule: `[blocks, block size, last block size, ...]`, the last size 0 when the data
    /// fills its blocks exactly), rewritten to give it the block size; `None` when there is none.
    /// vtkio 0.7.0-rc2 sizes the array `block size × (blocks − 1) + last block size` and so
    /// dropped a whole block of every array whose bytes are a multiple of the block size: VTK's
    /// zlib writer (blocks of 32 KiB) made such a file of any mesh of 4,096 × k cells
    /// (`offsets` of k blocks), which was refused. The first three words are the first 16 or 32
    /// base64 characters on their own, so the rewrite keeps every length.
    pub(crate) fn whole_last_blocks(&self, xml: &[u8]) -> Option<Vec<u8>> {
        let engine = &base64::engine::general_purpose::STANDARD;
        let chars = 4 * self.header_bytes;
        let mut patched: Option<Vec<u8>> = None;
        for &start in &self.starts {
            let Some(head) = xml.get(start..start + chars) else {
                continue;
            };
            let Ok(mut bytes) = engine.decode(head) else {
                continue;
            };
            if bytes.len() != 3 * self.header_bytes {
                continue;
            }
            let word = |bytes: &[u8], k: usize| {
                header_word(
                    &bytes[k * self.header_bytes..(k + 1) * self.header_bytes],
                    self.little,
                )
            };
            let (blocks, block_size, last) = (word(&bytes, 0), word(&bytes, 1), word(&bytes, 2));
            if blocks == 0 || last != 0 || block_size == 0 {
                continue;
            }
            let size = &mut bytes[2 * self.header_bytes..];
            match (self.header_bytes, self.little) {
                (8, true) => size.copy_from_slice(&block_size.to_le_bytes()),
                (8, false) => size.copy_from_slice(&block_size.to_be_bytes()),
                // A 4-byte header's block size fits 4 bytes (it was read from 4).
                (_, true) => size.copy_from_slice(&(block_size as u32).to_le_bytes()),
                (_, false) => size.copy_from_slice(&(block_size as u32).to_be_bytes()),
            }
            let text = patched.get_or_insert_with(|| xml.to_vec());
            text[start..start + chars].copy_from_slice(engine.encode(&bytes).as_bytes());
        }
        patched
    }
}

/// Refuse a compressed array whose header asks for more memory than its text could ever decompress
/// to. Returns where the compressed arrays' headers are (none when the file names no compressor).
pub(crate) fn check(xml: &[u8]) -> Result<Headers, ErrorKind> {
    let none = Headers::default;
    let Some(vtkfile_start) = find(xml, b"<VTKFile", 0) else {
        return Ok(none());
    };
    let Some(vtkfile_end) = find(xml, b">", vtkfile_start) else {
        return Ok(none());
    };
    let vtkfile = &xml[vtkfile_start..vtkfile_end];
    if attribute(vtkfile, b"compressor").is_none_or(|c| c.is_empty()) {
        return Ok(none());
    }
    let zlib =
        attribute(vtkfile, b"compressor").as_deref() == Some(b"vtkZLibDataCompressor".as_slice());
    let little = attribute(vtkfile, b"byte_order").as_deref() == Some(b"LittleEndian".as_slice());
    let header_bytes =
        if attribute(vtkfile, b"header_type").as_deref() == Some(b"UInt64".as_slice()) {
            8
        } else {
            4
        };
    let mut headers = Headers {
        starts: Vec::new(),
        header_bytes,
        little,
    };
    // The base64 appended data: from after the `_` to the next `<` (`</AppendedData>`).
    let appended = find(xml, b"<AppendedData", 0).and_then(|tag| {
        let end = find(xml, b">", tag)?;
        let encoding = attribute(&xml[tag..end], b"encoding");
        (encoding.as_deref() == Some(b"base64".as_slice()))
            .then(|| find(xml, b"_", end).map(|u| u + 1))
            .flatten()
            .map(|start| start..find(xml, b"<", start).unwrap_or(xml.len()))
    });
    let refuse = |tag: &[u8], message: String| {
        let name = attribute(tag, b"Name").map(|n| String::from_utf8_lossy(&n).into_owned());
        ErrorKind::Vtk(format!(
            "compressed array {}: {message}",
            name.map_or_else(|| "(unnamed)".to_owned(), |n| format!("`{n}`"))
        ))
    };

    // Appended arrays are checked once the walk has seen every offset: an array's text is then
    // its own block, up to the next array's offset, not the whole rest of the data (scanning
    // that for each of many arrays was quadratic).
    let mut appended_arrays: Vec<(usize, std::ops::Range<usize>)> = Vec::new();
    let mut at = 0;
    while let Some(tag_start) = find(xml, b"<DataArray", at) {
        let Some(tag_end) = find(xml, b">", tag_start) else {
            return Ok(headers);
        };
        at = tag_end;
        let tag = &xml[tag_start..tag_end];
        match attribute(tag, b"format").as_deref() {
            Some(b"binary") => {
                let text = xml[tag_end + 1..].trim_ascii_start();
                headers.starts.push(xml.len() - text.len());
                let length = text.iter().position(|&b| b == b'<').unwrap_or(text.len());
                at = tag_end + length;
                check_header(&text[..length], header_bytes, little, zlib)
                    .map_err(|message| refuse(tag, message))?;
            }
            Some(b"appended") => {
                let (Some(_), Some(offset)) = (&appended, attribute(tag, b"offset")) else {
                    continue;
                };
                let offset = std::str::from_utf8(&offset)
                    .ok()
                    .and_then(|o| o.trim().parse::<usize>().ok());
                if let Some(offset) = offset {
                    appended_arrays.push((offset, tag_start..tag_end));
                }
            }
            _ => {}
        }
    }
    let Some(data) = appended else {
        return Ok(headers);
    };
    let mut offsets: Vec<usize> = appended_arrays.iter().map(|(o, _)| *o).collect();
    offsets.sort_unstable();
    offsets.dedup();
    let mut checked = vec![false; offsets.len()];
    for (offset, tag) in appended_arrays {
        let k = offsets.partition_point(|&o| o < offset);
        if std::mem::replace(&mut checked[k], true) {
            continue;
        }
        let start = data.start.saturating_add(offset).min(data.end);
        let end = offsets.get(k + 1).map_or(data.end, |&next| {
            data.start.saturating_add(next).min(data.end)
        });
        let text = xml[start..end].trim_ascii();
        headers
            .starts
            .push(end - xml[start..end].trim_ascii_start().len());
        check_header(text, header_bytes, little, zlib)
            .map_err(|message| refuse(&xml[tag], message))?;
    }
    Ok(headers)
}

/// Check the first three header values of one compressed array held in base64 `text`.
fn check_header(text: &[u8], header_bytes: usize, little: bool, zlib: bool) -> Result<(), String> {
    // The header is base64-encoded on its own, from the start of the text: the first three values
    // (3 × 4 or 3 × 8 bytes, a multiple of 3) decode from exactly the first 16 or 32 characters.
    let chars = header_bytes * 4;
    let Some(head) = text.get(..chars) else {
        // Too short to hold a header: vtkio reports that itself, without a large allocation.
        return Ok(());
    };
    // Undecodable or padded short: not a header vtkio could read either; it reports that itself.
    let bytes = match base64::engine::general_purpose::STANDARD.decode(head) {
        Ok(bytes) if bytes.len() >= 3 * header_bytes => bytes,
        _ => return Ok(()),
    };
    let value = |k: usize| {
        u128::from(header_word(
            &bytes[k * header_bytes..(k + 1) * header_bytes],
            little,
        ))
    };
    let (blocks, block_size, last) = (value(0), value(1), value(2));
    if blocks == 0 {
        // vtkio computes `block size × (blocks − 1)` in usize: with no block, any block size wraps.
        return if block_size == 0 && last == 0 {
            Ok(())
        } else {
            Err(format!("its header says 0 blocks of {block_size} bytes"))
        };
    }
    let total = block_size.saturating_mul(blocks - 1).saturating_add(last);
    if !plausible_size(total, text.len() as u128) || blocks > text.len() as u128 {
        return Err(format!(
            "its header says {blocks} block(s) of {block_size} bytes ({total} bytes in all), more than \
             the {} bytes of text holding it could decompress to",
            text.len()
        ));
    }
    if zlib {
        check_zlib_blocks(text, header_bytes, little, blocks, block_size, last)?;
    }
    Ok(())
}

/// Whether each zlib block decompresses to exactly the size the header gives it: vtkio reads a
/// block into a buffer of that size and ignores what the stream holds beyond it, so a block
/// larger than its header said was read in part, without a word. Each block is decompressed
/// into nothing, at most one byte past its size, so a block that expands without end costs no
/// more than its header's claim, which `plausible_size` has bounded. What cannot be decoded is
/// left to vtkio, which drops the array (an error naming it, later).
fn check_zlib_blocks(
    text: &[u8],
    header_bytes: usize,
    little: bool,
    blocks: u128,
    block_size: u128,
    last: u128,
) -> Result<(), String> {
    use std::io::Read as _;
    let engine = &base64::engine::general_purpose::STANDARD;
    let chars = |bytes: usize| bytes.div_ceil(3).saturating_mul(4);
    // `blocks` is at most the text's length (checked above).
    let blocks = blocks as usize;
    let header_length = header_bytes * (3 + blocks);
    let Some(Ok(header)) = text.get(..chars(header_length)).map(|h| engine.decode(h)) else {
        return Ok(());
    };
    let Some(sizes) = header.get(3 * header_bytes..header_length) else {
        return Ok(());
    };
    let sizes: Vec<u64> = sizes
        .chunks_exact(header_bytes)
        .map(|w| header_word(w, little))
        .collect();
    let total = sizes.iter().fold(0u64, |t, &s| t.saturating_add(s));
    let Ok(total) = usize::try_from(total) else {
        return Ok(());
    };
    let start = chars(header_length);
    let Some(Ok(data)) = text
        .get(start..start.saturating_add(chars(total)))
        .map(|d| engine.decode(d))
    else {
        return Ok(());
    };
    let mut at = 0usize;
    for (k, &size) in sizes.iter().enumerate() {
        let Some(block) = usize::try_from(size)
            .ok()
            .and_then(|size| data.get(at..at.checked_add(size)?))
        else {
            return Ok(());
        };
        at += block.len();
        // The last block holds `last` bytes when that is not 0.
        let expected = if k + 1 == blocks && last != 0 {
            last
        } else {
            block_size
        };
        let limit = u64::try_from(expected)
            .unwrap_or(u64::MAX)
            .saturating_add(1);
        let mut decoder = flate2::read::ZlibDecoder::new(block).take(limit);
        let Ok(produced) = std::io::copy(&mut decoder, &mut std::io::sink()) else {
            return Ok(());
        };
        if u128::from(produced) != expected {
            let relation = if u128::from(produced) > expected {
                "more than"
            } else {
                "fewer than"
            };
            return Err(format!(
                "zlib block {k} decompresses to {relation} the {expected} bytes its header gives"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(values: [u64; 4]) -> Vec<u8> {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        base64::engine::general_purpose::STANDARD
            .encode(bytes)
            .into_bytes()
    }

    #[test]
    fn plausible_headers_pass_absurd_ones_are_refused() {
        let mut text = header([1, 96, 96, 40]);
        text.extend_from_slice(&[b'A'; 60]);
        assert!(check_header(&text, 8, true, false).is_ok());
        let mut huge = header([1 << 20, 1 << 30, 5, 40]);
        huge.extend_from_slice(&[b'A'; 60]);
        let message = check_header(&huge, 8, true, false).unwrap_err();
        assert!(message.contains("1048576 block(s)"), "{message}");
    }
}
