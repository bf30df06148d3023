//! Decompressing the LZMA-compressed arrays of XML VTK files before vtkio sees them.
//!
//! VTK's `vtkLZMADataCompressor` (`SetCompressorTypeToLZMA()`, ParaView's "Save Data") compresses
//! each array in blocks, behind a header `[blocks, block size, last block size, compressed
//! sizes...]`, and writes each block as one `.xz` stream (`lzma_easy_buffer_encode`, a CRC32
//! check). vtkio 0.7.0-rc2 decompresses LZMA only through its `xz2` feature (liblzma, a C build),
//! which the workspace leaves off. So a file whose `compressor` is `vtkLZMADataCompressor` is
//! rewritten here as the same file uncompressed: every array, inline (`format="binary"`) or
//! appended (`encoding="raw"` or `"base64"`), is read with its header, each block is decompressed
//! with lzma-rs's pure-Rust `.xz` decoder and must come out exactly as large as the header says,
//! and the array is written back inline as base64 of `[size][bytes]`, the `compressor` attribute
//! and the `<AppendedData>` element removed. Inline, vtkio checks each array's length against the
//! tuples the file declares. Lines are kept: an error vtkio finds later names the original line.
//!
//! Memory: lzma-rs 0.3 has no output limit for `.xz` (its `memlimit` option is for raw LZMA
//! only) and decodes a whole block before its size can be compared, so before decoding anything,
//! each block must be one a real `.xz` writer could have produced for the size its header claims:
//!
//! - it claims at most [`MAX_EXPANSION`] (7,200) times its compressed bytes, plus 64 KiB: LZMA
//!   cannot do better than about 7,090 : 1 (its best symbol, a 273-byte repeat of the last
//!   match, takes 14 binary decisions of at least 0.022 bits each, the cost of the most likely
//!   outcome of an 11-bit probability that adapts by 1/32), and xz compresses 128 MiB of zeros
//!   6,828 : 1. Checked for the whole array before any block is decoded;
//! - it holds at most its claimed size plus 1/16,384 of it plus 2 KiB: liblzma stores data that
//!   does not compress as raw LZMA2 chunks (3 bytes of header per 64 KiB) in a frame of well
//!   under 2 KiB, so no `.xz` stream of that size is longer;
//! - the sizes in the headers of its LZMA2 chunks, read from the framing without decoding, add up
//!   to exactly the claimed size, and each `.xz` block has one filter (lzma-rs would run a chain
//!   of several, each expanding the last one's output). lzma-rs stops each chunk at its declared
//!   size, so it holds no more than the claimed size (plus one match, 273 bytes, per chunk);
//! - nothing is allocated from a header: the output grows as blocks are decoded, with
//!   `try_reserve`, so that even a memory exhausted is an error, not an abort.
//!
//! The one case these leave open is a stream crafted so that a chunk's range coder ends before
//! the chunk's compressed bytes do (liblzma refuses that; lzma-rs does not check it): lzma-rs then
//! reads the rest as further chunks, and one block may decode to LZMA's ratio times its
//! compressed bytes, which the second rule bounds by about 7,100 times the size its header
//! claims, before it is refused.

use std::ops::Range;

use base64::Engine as _;

use crate::ErrorKind;
use crate::raw_appended::{find, header_word};

/// The `compressor` attribute value of VTK's LZMA compressor.
const COMPRESSOR: &[u8] = b"vtkLZMADataCompressor";

/// Largest ratio of the bytes an LZMA block claims to its compressed bytes (see the module doc).
pub(crate) const MAX_EXPANSION: u64 = 7200;

/// Whether a block may claim `claimed` bytes from `held` compressed bytes: at most
/// [`MAX_EXPANSION`] times them, plus 64 KiB, as `block_headers::plausible_size` for zlib and LZ4.
fn plausible_size(claimed: u64, held: u64) -> bool {
    claimed <= MAX_EXPANSION.saturating_mul(held).saturating_add(1 << 16)
}

/// The most compressed bytes an `.xz` stream of `size` bytes needs (see the module doc).
fn xz_size_bound(size: u64) -> u64 {
    size.saturating_add(size / 16384).saturating_add(2048)
}

/// The file with its LZMA-compressed arrays decompressed, or `None` when its `compressor` is not
/// `vtkLZMADataCompressor`. A `compressor` VTK does not have is an error (vtkio would read the
/// data as uncompressed).
pub(crate) fn decompress(xml: &[u8]) -> Result<Option<Vec<u8>>, ErrorKind> {
    let Some(vtkfile_start) = find(xml, b"<VTKFile", 0) else {
        return Ok(None);
    };
    let Some(vtkfile_end) = find(xml, b">", vtkfile_start) else {
        return Ok(None);
    };
    let vtkfile = &xml[vtkfile_start..vtkfile_end];
    let Some((compressor, value)) = attribute_span(vtkfile, b"compressor") else {
        return Ok(None);
    };
    match &vtkfile[value] {
        COMPRESSOR => {}
        b"" | b"vtkZLibDataCompressor" | b"vtkLZ4DataCompressor" => return Ok(None),
        // vtkio reads a compressor it does not know as none: compressed data as raw.
        other => {
            return Err(ErrorKind::Vtk(format!(
                "line {}: compressor {} is none of VTK's (vtkZLibDataCompressor, \
                 vtkLZ4DataCompressor, vtkLZMADataCompressor)",
                line_of(xml, vtkfile_start),
                crate::excerpt(other, 40)
            )));
        }
    }
    let bad = |m: String| ErrorKind::Vtk(format!("LZMA-compressed file: {m}"));
    let value_of = |name: &[u8]| attribute_span(vtkfile, name).map(|(_, v)| &vtkfile[v]);
    let little = match value_of(b"byte_order") {
        Some(b"LittleEndian") => true,
        Some(b"BigEndian") | None => false,
        Some(other) => {
            return Err(bad(format!("byte_order {}", crate::excerpt(other, 40))));
        }
    };
    let header_bytes = match value_of(b"header_type") {
        Some(b"UInt64") => 8,
        Some(b"UInt32") | None => 4,
        Some(other) => {
            return Err(bad(format!("header_type {}", crate::excerpt(other, 40))));
        }
    };
    let layout = Layout {
        little,
        header_bytes,
    };

    let appended = appended_data(xml, vtkfile_end).map_err(bad)?;
    let head = &xml[..appended.as_ref().map_or(xml.len(), |a| a.element.start)];
    // (range of `head` replaced, by what), in order.
    let mut edits: Vec<(Range<usize>, Vec<u8>)> = vec![(
        vtkfile_start + compressor.start..vtkfile_start + compressor.end,
        Vec::new(),
    )];
    let mut at = vtkfile_end;
    while let Some(tag_start) = find(head, b"<DataArray", at) {
        let tag_end = find(head, b">", tag_start).ok_or_else(|| {
            bad(format!(
                "line {}: the file ends inside a <DataArray> tag (truncated?)",
                line_of(xml, tag_start)
            ))
        })?;
        at = tag_end + 1;
        let tag = &head[tag_start..tag_end];
        let name = attribute_span(tag, b"Name").map_or_else(
            || "(unnamed)".to_owned(),
            |(_, v)| crate::excerpt(&tag[v], 60),
        );
        let in_array = |place: usize, m: String| {
            ErrorKind::Vtk(format!(
                "LZMA-compressed array {name} (line {}, byte {place}): {m}",
                line_of(xml, place)
            ))
        };
        let self_closing = tag.ends_with(b"/");
        let format = attribute_span(tag, b"format").map(|(_, v)| v);
        match format.clone().map(|v| &tag[v]) {
            Some(b"binary") => {
                if self_closing {
                    return Err(in_array(tag_start, "an inline array without data".into()));
                }
                let text_end = find(head, b"<", at).unwrap_or(head.len());
                let text = &head[at..text_end];
                let start = at + (text.len() - text.trim_ascii_start().len());
                let text = text.trim_ascii();
                let (bytes, used) = base64_array(text, &layout).map_err(|m| in_array(start, m))?;
                if used != text.len() {
                    return Err(in_array(
                        start + used,
                        format!("{} characters after the array's data", text.len() - used),
                    ));
                }
                let encoded = uncompressed(&bytes, &layout).map_err(|m| in_array(start, m))?;
                edits.push((start..start + text.len(), encoded));
            }
            Some(b"appended") => {
                let Some(appended) = &appended else {
                    return Err(in_array(
                        tag_start,
                        "an appended array, but the file has no <AppendedData>".into(),
                    ));
                };
                let (offset_attribute, offset_value) =
                    attribute_span(tag, b"offset").ok_or_else(|| {
                        in_array(tag_start, "an appended array without an offset".into())
                    })?;
                let offset = std::str::from_utf8(&tag[offset_value.clone()])
                    .ok()
                    .and_then(|o| o.trim().parse::<usize>().ok())
                    .ok_or_else(|| {
                        in_array(
                            tag_start,
                            format!(
                                "offset {} is not a byte count",
                                crate::excerpt(&tag[offset_value], 40)
                            ),
                        )
                    })?;
                let data = appended.data.clone();
                let place = data.start.saturating_add(offset);
                let text = xml[data].get(offset..).ok_or_else(|| {
                    in_array(
                        tag_start,
                        format!(
                            "offset {offset} is past the end of the appended data ({} bytes)",
                            appended.data.len()
                        ),
                    )
                })?;
                let bytes = if appended.raw {
                    raw_array(text, &layout)
                } else {
                    base64_array(text, &layout).map(|(bytes, _)| bytes)
                }
                .map_err(|m| in_array(place, m))?;
                let encoded = uncompressed(&bytes, &layout).map_err(|m| in_array(place, m))?;
                // `format="appended" offset="N"` becomes `format="binary"` and the data go inline,
                // where VTK writes them: right after the start tag.
                if let Some(format) = format {
                    edits.push((
                        tag_start + format.start..tag_start + format.end,
                        b"binary".to_vec(),
                    ));
                }
                edits.push((
                    tag_start + offset_attribute.start..tag_start + offset_attribute.end,
                    Vec::new(),
                ));
                if self_closing {
                    let mut text = b">".to_vec();
                    text.extend_from_slice(&encoded);
                    text.extend_from_slice(b"</DataArray>");
                    edits.push((tag_end - 1..tag_end + 1, text));
                } else {
                    edits.push((tag_end + 1..tag_end + 1, encoded));
                }
            }
            _ => {}
        }
    }

    edits.sort_by_key(|(range, _)| range.start);
    let mut out = Vec::with_capacity(xml.len());
    let mut copied = 0;
    for (range, text) in edits {
        // Attributes found inside other attributes' values could overlap.
        let kept = head.get(copied..range.start).ok_or_else(|| {
            bad(format!(
                "line {}: overlapping attributes",
                line_of(xml, range.start)
            ))
        })?;
        out.extend_from_slice(kept);
        out.extend_from_slice(&text);
        copied = range.end;
    }
    out.extend_from_slice(&head[copied..]);
    if let Some(appended) = appended {
        out.extend_from_slice(&xml[appended.element.end..]);
    }
    Ok(Some(out))
}

/// How a file's block headers are written.
struct Layout {
    little: bool,
    /// 4 (`UInt32`) or 8 (`UInt64`).
    header_bytes: usize,
}

/// The `<AppendedData>` element of a file.
struct Appended {
    /// From `<AppendedData` to the end of `</AppendedData>`.
    element: Range<usize>,
    /// The bytes after the `_`, up to `</AppendedData>`.
    data: Range<usize>,
    raw: bool,
}

fn appended_data(xml: &[u8], from: usize) -> Result<Option<Appended>, String> {
    let Some(start) = find(xml, b"<AppendedData", from) else {
        return Ok(None);
    };
    let tag_end = find(xml, b">", start).ok_or("the file ends inside the <AppendedData> tag")?;
    let tag = &xml[start..tag_end];
    let raw = match attribute_span(tag, b"encoding").map(|(_, v)| &tag[v]) {
        Some(b"raw") => true,
        Some(b"base64") => false,
        other => {
            return Err(format!(
                "<AppendedData> with encoding {}",
                other.map_or_else(|| "(none)".to_owned(), |e| crate::excerpt(e, 40))
            ));
        }
    };
    let underscore = find(xml, b"_", tag_end).ok_or("no `_` before the appended data")?;
    const CLOSE: &[u8] = b"</AppendedData>";
    // Raw bytes may hold anything: the element ends at the last closing tag.
    let close = if raw {
        xml.windows(CLOSE.len()).rposition(|w| w == CLOSE)
    } else {
        find(xml, CLOSE, underscore)
    }
    .filter(|&c| c > underscore)
    .ok_or_else(|| {
        format!(
            "line {}: the file ends inside <AppendedData> (truncated?)",
            line_of(xml, start)
        )
    })?;
    Ok(Some(Appended {
        element: start..close + CLOSE.len(),
        data: underscore + 1..close,
        raw,
    }))
}

/// One compressed array in base64 at the start of `text` (its header, then its blocks, two base64
/// runs as VTK writes them): its bytes decompressed, and the characters it takes.
fn base64_array(text: &[u8], layout: &Layout) -> Result<(Vec<u8>, usize), String> {
    let b64 = |bytes: u64| bytes.div_ceil(3).saturating_mul(4);
    let decode = |chars: &[u8], what: &str| {
        base64::engine::general_purpose::STANDARD
            .decode(chars)
            .map_err(|e| format!("its {what} is not base64 ({e})"))
    };
    let hb = layout.header_bytes as u64;
    let first = text
        .get(..b64(hb) as usize)
        .ok_or("too short for a block header")?;
    let first = decode(first, "block header")?;
    let blocks = header_word(
        first
            .get(..layout.header_bytes)
            .ok_or("its block header is cut by base64 padding")?,
        layout.little,
    );
    // Each block takes at least one character: refuse a count the text cannot hold before sizing
    // anything from it.
    if blocks > text.len() as u64 {
        return Err(format!(
            "its header says {blocks} blocks, more than its {} characters can hold",
            text.len()
        ));
    }
    let header_chars = b64((3 + blocks) * hb);
    let header = text
        .get(..header_chars as usize)
        .ok_or_else(|| format!("its header of {blocks} blocks runs past its text"))?;
    let header = decode(header, "block header")?;
    let words = words(&header, layout);
    let total = compressed_total(&words)?;
    let data_chars = b64(total);
    let end = header_chars.saturating_add(data_chars);
    let data = usize::try_from(end)
        .ok()
        .and_then(|end| text.get(header_chars as usize..end))
        .ok_or_else(|| {
            format!(
                "its header says {total} compressed bytes ({data_chars} characters of base64), \
                 but only {} characters follow it (truncated?)",
                text.len() as u64 - header_chars
            )
        })?;
    let data = decode(data, "compressed data")?;
    Ok((decompress_blocks(&words, &data)?, end as usize))
}

/// One compressed array in raw bytes at the start of `data`: its bytes decompressed.
fn raw_array(data: &[u8], layout: &Layout) -> Result<Vec<u8>, String> {
    let hb = layout.header_bytes;
    let first = data.get(..hb).ok_or("too short for a block header")?;
    let blocks = header_word(first, layout.little);
    if blocks > data.len() as u64 {
        return Err(format!(
            "its header says {blocks} blocks, more than the {} bytes after it can hold",
            data.len()
        ));
    }
    let header_len = (3 + blocks as usize) * hb;
    let header = data
        .get(..header_len)
        .ok_or_else(|| format!("its header of {blocks} blocks runs past the appended data"))?;
    let words = words(header, layout);
    let total = compressed_total(&words)?;
    let body = data
        .get(header_len..)
        .and_then(|rest| rest.get(..usize::try_from(total).ok()?))
        .ok_or_else(|| {
            format!(
                "its header says {total} compressed bytes, but only {} follow it (truncated?)",
                data.len() - header_len
            )
        })?;
    decompress_blocks(&words, body)
}

fn words(header: &[u8], layout: &Layout) -> Vec<u64> {
    header
        .chunks_exact(layout.header_bytes)
        .map(|w| header_word(w, layout.little))
        .collect()
}

/// The compressed bytes of all blocks of a header `[blocks, block size, last size, sizes...]`.
fn compressed_total(words: &[u64]) -> Result<u64, String> {
    words
        .get(3..)
        .ok_or("its block header is cut")?
        .iter()
        .try_fold(0u64, |sum, &size| sum.checked_add(size))
        .ok_or_else(|| "its compressed block sizes overflow".to_owned())
}

/// Decompress the blocks `data` holds, as the header `words` describes them.
fn decompress_blocks(words: &[u64], data: &[u8]) -> Result<Vec<u8>, String> {
    let [blocks, block_size, last_size, ref sizes @ ..] = *words else {
        return Err("its block header is cut".into());
    };
    if sizes.len() as u64 != blocks {
        return Err(format!(
            "its header says {blocks} blocks but holds {} compressed sizes",
            sizes.len()
        ));
    }
    if last_size > block_size {
        return Err(format!(
            "its header says blocks of {block_size} bytes and a last block of {last_size}"
        ));
    }
    if blocks == 0 {
        return if last_size == 0 {
            Ok(Vec::new())
        } else {
            Err(format!(
                "its header says 0 blocks and a last block of {last_size} bytes"
            ))
        };
    }
    // The last block's size, 0 when it is a whole block (VTK's rule).
    let claimed = |b: usize| {
        if b + 1 == sizes.len() && last_size != 0 {
            last_size
        } else {
            block_size
        }
    };
    let total_claimed = block_size
        .saturating_mul(blocks - 1)
        .saturating_add(claimed(sizes.len() - 1));
    let total_held = compressed_total(words)?;
    if !plausible_size(total_claimed, total_held) {
        return Err(format!(
            "its header says {blocks} block(s) of {block_size} bytes ({total_claimed} bytes in \
             all) from {total_held} compressed bytes, more than LZMA can expand \
             ({MAX_EXPANSION} : 1)"
        ));
    }
    let mut out: Vec<u8> = Vec::new();
    let mut at = 0usize;
    for (b, &held) in sizes.iter().enumerate() {
        let size = claimed(b);
        let place = |m: String| {
            format!(
                "block {b} of {blocks} (compressed bytes {at}..{} of the array): {m}",
                at as u64 + held
            )
        };
        if !plausible_size(size, held) {
            return Err(place(format!(
                "its header says {size} bytes from {held} compressed bytes, more than LZMA can \
                 expand ({MAX_EXPANSION} : 1)"
            )));
        }
        if held > xz_size_bound(size) {
            return Err(place(format!(
                "{held} compressed bytes for {size} bytes, more than an .xz stream of that \
                 size takes"
            )));
        }
        let stream = usize::try_from(held)
            .ok()
            .and_then(|held| data.get(at..at.checked_add(held)?))
            .ok_or_else(|| place("runs past the array's data".into()))?;
        let framed = xz_framed_size(stream).map_err(&place)?;
        if framed != size {
            return Err(place(format!(
                "its .xz stream's LZMA2 chunks hold {framed} bytes, its header says {size}"
            )));
        }
        let mut block = Vec::new();
        lzma_rs::xz_decompress(&mut &stream[..], &mut block).map_err(|e| place(xz_error(&e)))?;
        if block.len() as u64 != size {
            return Err(place(format!(
                "decompressed to {} bytes, its header says {size}",
                block.len()
            )));
        }
        out.try_reserve(block.len())
            .map_err(|e| place(format!("{e}")))?;
        out.extend_from_slice(&block);
        at += held as usize;
    }
    Ok(out)
}

/// lzma-rs's error, a stream that ends early said so.
fn xz_error(error: &lzma_rs::error::Error) -> String {
    use lzma_rs::error::Error;
    match error {
        Error::IoError(e) | Error::HeaderTooShort(e)
            if e.kind() == std::io::ErrorKind::UnexpectedEof =>
        {
            "the .xz stream ends early (cut short?)".to_owned()
        }
        other => other.to_string(),
    }
}

/// The bytes an `.xz` stream decompresses to, from the headers of its LZMA2 chunks alone (without
/// decoding them). Refuses what lzma-rs would decode with more memory than that: a block with
/// several filters.
fn xz_framed_size(stream: &[u8]) -> Result<u64, String> {
    const MAGIC: &[u8] = b"\xFD7zXZ\0";
    let cut = || "the .xz stream is cut short".to_owned();
    if !stream.starts_with(MAGIC) {
        return Err(format!(
            "not an .xz stream (it starts with {})",
            crate::excerpt(&stream[..stream.len().min(6)], 12)
        ));
    }
    let byte = |at: usize| stream.get(at).copied().ok_or_else(cut);
    let u16_at =
        |at: usize| Ok::<u64, String>(u64::from(byte(at)?) << 8 | u64::from(byte(at + 1)?));
    let check = match byte(7)? & 0x0F {
        0 => 0,
        1 => 4,
        4 => 8,
        10 => 32,
        other => return Err(format!("unknown .xz check type {other}")),
    };
    let mut at = 12;
    let mut total = 0u64;
    // Each pass moves `at` forward, so this ends at the index or at the end of the stream.
    loop {
        let header_size = byte(at)?;
        if header_size == 0 {
            return Ok(total);
        }
        let block_start = at;
        if byte(at + 1)? & 0x03 != 0 {
            return Err("an .xz block with more than one filter (VTK writes LZMA2 alone)".into());
        }
        at += (usize::from(header_size) + 1) * 4;
        loop {
            let control = byte(at)?;
            match control {
                0 => {
                    at += 1;
                    break;
                }
                1 | 2 => {
                    let size = u16_at(at + 1)? + 1;
                    total += size;
                    at += 3 + size as usize;
                }
                0x80.. => {
                    total += (u64::from(control & 0x1F) << 16 | u16_at(at + 1)?) + 1;
                    let packed = u16_at(at + 3)? as usize + 1;
                    at += 5 + usize::from(control >= 0xC0) + packed;
                }
                _ => {
                    return Err(format!(
                        "LZMA2 control byte {control:#04x} at byte {at} of the .xz stream"
                    ));
                }
            }
        }
        // Padding to a multiple of 4 bytes from the block's start, then the check.
        at += (4 - (at - block_start) % 4) % 4 + check;
    }
}

/// `bytes` as VTK writes an uncompressed inline array: base64 of the size, then the bytes.
fn uncompressed(bytes: &[u8], layout: &Layout) -> Result<Vec<u8>, String> {
    let size = bytes.len() as u64;
    let mut block = Vec::new();
    block
        .try_reserve(layout.header_bytes + bytes.len())
        .map_err(|e| e.to_string())?;
    match (layout.header_bytes, layout.little) {
        (8, true) => block.extend(size.to_le_bytes()),
        (8, false) => block.extend(size.to_be_bytes()),
        (_, little) => {
            let size = u32::try_from(size).map_err(|_| {
                format!("{size} bytes decompressed, more than a UInt32 header_type can describe")
            })?;
            block.extend(if little {
                size.to_le_bytes()
            } else {
                size.to_be_bytes()
            });
        }
    }
    block.extend_from_slice(bytes);
    Ok(base64::engine::general_purpose::STANDARD
        .encode(block)
        .into_bytes())
}

/// Where attribute `name` is in a start tag: the whole attribute with the white space before it,
/// and its value (as `raw_appended::attribute` finds it).
fn attribute_span(tag: &[u8], name: &[u8]) -> Option<(Range<usize>, Range<usize>)> {
    let mut at = 0;
    while let Some(i) = find(tag, name, at) {
        at = i + name.len();
        if i == 0 || !tag[i - 1].is_ascii_whitespace() {
            continue;
        }
        let mut j = at;
        let skip = |mut j: usize| {
            while tag.get(j).is_some_and(u8::is_ascii_whitespace) {
                j += 1;
            }
            j
        };
        j = skip(j);
        if tag.get(j) != Some(&b'=') {
            continue;
        }
        j = skip(j + 1);
        let quote = *tag.get(j)?;
        if quote != b'"' && quote != b'\'' {
            continue;
        }
        let end = j + 1 + tag[j + 1..].iter().position(|&b| b == quote)?;
        return Some((i - 1..end + 1, j + 1..end));
    }
    None
}

/// The 1-based line of byte `at`.
fn line_of(xml: &[u8], at: usize) -> usize {
    1 + xml[..at.min(xml.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attribute_spans_cover_the_attribute_and_its_value() {
        let tag = b"<VTKFile type=\"U\" compressor = 'vtkLZMADataCompressor' x=\"1\"";
        let (whole, value) = attribute_span(tag, b"compressor").unwrap();
        assert_eq!(&tag[whole], b" compressor = 'vtkLZMADataCompressor'");
        assert_eq!(&tag[value], COMPRESSOR);
        assert!(attribute_span(tag, b"ompressor").is_none());
    }

    #[test]
    fn lzma_rs_streams_frame_to_their_size() {
        for size in [0usize, 1, 70_000] {
            let data: Vec<u8> = (0..size).map(|i| (i * 7 % 251) as u8).collect();
            let mut stream = Vec::new();
            lzma_rs::xz_compress(&mut data.as_slice(), &mut stream).unwrap();
            assert_eq!(xz_framed_size(&stream).unwrap(), size as u64);
            assert!(stream.len() as u64 <= xz_size_bound(size as u64));
        }
    }

    #[test]
    fn implausible_blocks_are_refused_before_decoding() {
        // 1 block claiming 2^40 bytes from 100 compressed bytes.
        let words = [1, 1 << 40, 0, 100];
        let message = decompress_blocks(&words, &[0; 100]).unwrap_err();
        assert!(message.contains("more than LZMA can expand"), "{message}");
        // A block claiming 10 bytes held in 5,000: no .xz stream of 10 bytes is that long.
        let words = [1, 10, 0, 5000];
        let message = decompress_blocks(&words, &[0; 5000]).unwrap_err();
        assert!(message.contains("more than an .xz stream"), "{message}");
    }
}
