//! Re-encoding raw appended data of XML VTK files as base64.
//!
//! ParaView and VTK write `.vtu` files with `<AppendedData encoding="raw">` by default: the arrays'
//! bytes follow an `_` verbatim. vtkio 0.7.0-rc2 reads appended data only in base64 (its `Raw`
//! encoding sits behind a `binary` feature that its manifest does not declare), so before handing
//! such a file to vtkio we re-encode each array's block as base64 exactly as VTK's base64 appended
//! mode lays it out, and rewrite the `offset` attributes to point into the encoded text. Everything
//! else, decompression included, stays vtkio's job.

use crate::ErrorKind;

/// The file re-encoded with base64 appended data, or `None` when it has no raw appended data.
pub(crate) fn to_base64(xml: &[u8]) -> Result<Option<Vec<u8>>, ErrorKind> {
    let Some(tag_start) = find(xml, b"<AppendedData", 0) else {
        return Ok(None);
    };
    let bad = |m: String| ErrorKind::Vtk(format!("raw appended data: {m}"));
    let tag_end =
        find(xml, b">", tag_start).ok_or_else(|| bad("unterminated <AppendedData> tag".into()))?;
    let tag = &xml[tag_start..tag_end];
    if attribute(tag, b"encoding").as_deref() != Some(b"raw".as_slice()) {
        return Ok(None);
    }
    let head = &xml[..tag_start];
    let vtkfile_start =
        find(head, b"<VTKFile", 0).ok_or_else(|| bad("no <VTKFile> element".into()))?;
    let vtkfile_end =
        find(head, b">", vtkfile_start).ok_or_else(|| bad("unterminated <VTKFile> tag".into()))?;
    let vtkfile = &head[vtkfile_start..vtkfile_end];
    let little = match attribute(vtkfile, b"byte_order").as_deref() {
        Some(b"LittleEndian") => true,
        Some(b"BigEndian") | None => false,
        Some(other) => {
            return Err(bad(format!(
                "byte_order `{}`",
                String::from_utf8_lossy(other)
            )));
        }
    };
    let header_bytes = match attribute(vtkfile, b"header_type").as_deref() {
        Some(b"UInt64") => 8,
        Some(b"UInt32") | None => 4,
        Some(other) => {
            return Err(bad(format!(
                "header_type `{}`",
                String::from_utf8_lossy(other)
            )));
        }
    };
    let compressed = attribute(vtkfile, b"compressor").is_some_and(|c| !c.is_empty());

    // The data start after the first `_` past the tag and end before the last `</AppendedData>`.
    let underscore =
        find(xml, b"_", tag_end).ok_or_else(|| bad("no `_` before the data".into()))?;
    let data_end = rfind(xml, b"</AppendedData>")
        .filter(|&e| e > underscore)
        .unwrap_or(xml.len());
    let data = &xml[underscore + 1..data_end];
    let tail = if data_end < xml.len() {
        &xml[data_end..]
    } else {
        b"</AppendedData>\n</VTKFile>\n".as_slice()
    };

    let read = |at: usize| -> Result<usize, ErrorKind> {
        let bytes = data.get(at..at + header_bytes).ok_or_else(|| {
            bad(format!(
                "a block header at byte {at} runs past the data ({} bytes)",
                data.len()
            ))
        })?;
        let v = header_word(bytes, little);
        usize::try_from(v).map_err(|_| bad(format!("block size {v} at byte {at}")))
    };

    // Every `offset="N"` in the head names one array's block.
    let offsets = offset_attributes(head).map_err(bad)?;
    let mut distinct: Vec<usize> = offsets.iter().map(|o| o.value).collect();
    distinct.sort_unstable();
    distinct.dedup();
    let mut encoded = Vec::new();
    let mut new_offset = std::collections::HashMap::new();
    for (k, &at) in distinct.iter().enumerate() {
        // Blocks follow one another: one running into the next array's block is the wrong size
        // (vtkio reads uncompressed base64 blocks by the array's length and ignores the header).
        let next = distinct.get(k + 1).copied().unwrap_or(data.len());
        new_offset.insert(at, encoded.len());
        if compressed {
            let blocks = read(at)?;
            let full = header_bytes
                .checked_mul(
                    blocks
                        .checked_add(3)
                        .ok_or_else(|| bad("block count overflows".into()))?,
                )
                .ok_or_else(|| bad("block count overflows".into()))?;
            let mut total = 0usize;
            for b in 0..blocks {
                total = total
                    .checked_add(read(at + header_bytes * (3 + b))?)
                    .ok_or_else(|| bad("sizes overflow".into()))?;
            }
            // vtkio allocates the decompressed size from this header before decompressing: refuse
            // sizes that no zlib/LZ4 stream of this length can produce (`plausible_size`, the test
            // of `block_headers` too), so that a corrupt header is an error, not an allocation
            // failure.
            let block_size = read(at + header_bytes)?;
            let last_size = read(at + 2 * header_bytes)?;
            let claimed = block_size
                .saturating_mul(blocks.saturating_sub(1))
                .saturating_add(last_size);
            if blocks == 0 || !crate::block_headers::plausible_size(claimed as u128, total as u128)
            {
                return Err(bad(format!(
                    "block at byte {at} claims {claimed} bytes from {total} compressed in {blocks} blocks"
                )));
            }
            let header = data
                .get(at..at + full)
                .ok_or_else(|| bad(format!("block header at byte {at} is cut")))?;
            let body = data
                .get(at + full..at + full + total)
                .ok_or_else(|| bad(format!("compressed block at byte {at} runs past the data")))?;
            // VTK encodes a compressed block's header and its data as two base64 runs.
            encoded.extend(encode(header));
            encoded.extend(encode(body));
        } else {
            let size = read(at)?;
            let end = (at + header_bytes).saturating_add(size);
            let block = data.get(at..end).ok_or_else(|| {
                bad(format!(
                    "block at byte {at} of {size} bytes runs past the data"
                ))
            })?;
            if end > next {
                return Err(bad(format!(
                    "array {}: the block at byte {at} says it holds {size} bytes, {} more than there are \
                     before the next array's block at byte {next}",
                    array_name(head, &offsets, at),
                    end - next
                )));
            }
            encoded.extend(encode(block));
        }
    }

    let mut out = Vec::with_capacity(head.len() + encoded.len() + 64);
    let mut copied = 0;
    for o in &offsets {
        out.extend_from_slice(&head[copied..o.start]);
        out.extend_from_slice(new_offset[&o.value].to_string().as_bytes());
        copied = o.end;
    }
    out.extend_from_slice(&head[copied..]);
    out.extend_from_slice(b"<AppendedData encoding=\"base64\">\n_");
    out.extend_from_slice(&encoded);
    out.extend_from_slice(b"\n");
    out.extend_from_slice(tail);
    Ok(Some(out))
}

/// The name of the first array whose block is at byte `at`, quoted, for messages.
fn array_name(head: &[u8], offsets: &[Offset], at: usize) -> String {
    offsets
        .iter()
        .find(|o| o.value == at)
        .and_then(|o| {
            let tag = rfind(&head[..o.start], b"<DataArray")?;
            attribute(&head[tag..o.start], b"Name")
        })
        .map_or_else(|| "(unnamed)".to_owned(), |n| crate::excerpt(&n, 60))
}

/// An `offset="N"` attribute: the digits' byte range in the head and their value.
struct Offset {
    start: usize,
    end: usize,
    value: usize,
}

fn offset_attributes(head: &[u8]) -> Result<Vec<Offset>, String> {
    let mut found = Vec::new();
    let mut at = 0;
    while let Some(i) = find(head, b"offset", at) {
        at = i + 6;
        // A whole attribute name: preceded by white space, followed by `=`.
        if i == 0 || !head[i - 1].is_ascii_whitespace() {
            continue;
        }
        let mut j = at;
        while j < head.len() && head[j].is_ascii_whitespace() {
            j += 1;
        }
        if head.get(j) != Some(&b'=') {
            continue;
        }
        j += 1;
        while j < head.len() && head[j].is_ascii_whitespace() {
            j += 1;
        }
        let Some(&quote) = head.get(j).filter(|q| **q == b'"' || **q == b'\'') else {
            continue;
        };
        let start = j + 1;
        let end = start
            + head[start..]
                .iter()
                .position(|&b| b == quote)
                .ok_or("unterminated offset attribute")?;
        let text =
            std::str::from_utf8(&head[start..end]).map_err(|_| "offset is not text".to_owned())?;
        let value = text.trim().parse().map_err(|_| {
            format!(
                "offset {} is not a byte count",
                crate::excerpt(text.as_bytes(), 40)
            )
        })?;
        found.push(Offset { start, end, value });
        at = end;
    }
    Ok(found)
}

/// The value of attribute `name` in a start tag.
pub(crate) fn attribute(tag: &[u8], name: &[u8]) -> Option<Vec<u8>> {
    let mut at = 0;
    while let Some(i) = find(tag, name, at) {
        at = i + name.len();
        if i == 0 || !tag[i - 1].is_ascii_whitespace() {
            continue;
        }
        // The name may also occur inside another attribute's value (`Name="an offset"`): only
        // `name = "value"` is the attribute.
        let rest = tag[at..].trim_ascii_start();
        let Some(rest) = rest.strip_prefix(b"=") else {
            continue;
        };
        let rest = rest.trim_ascii_start();
        let Some(&quote) = rest.first().filter(|&&q| q == b'"' || q == b'\'') else {
            continue;
        };
        let end = rest[1..].iter().position(|&b| b == quote)?;
        return Some(rest[1..1 + end].to_vec());
    }
    None
}

/// An unsigned block-header word (VTK's `header_type`, 4 or 8 bytes) in the file's byte order.
pub(crate) fn header_word(word: &[u8], little: bool) -> u64 {
    let push = |v: u64, &b: &u8| (v << 8) | u64::from(b);
    if little {
        word.iter().rev().fold(0, push)
    } else {
        word.iter().fold(0, push)
    }
}

/// The appended data of the `<AppendedData` tag at `tag` of `xml`: from after the `_` that
/// opens it to the end of the file. `None` when the tag is not closed or no `_` follows.
pub(crate) fn appended_text(xml: &[u8], tag: usize) -> Option<&[u8]> {
    let close = find(xml, b">", tag)?;
    let underscore = find(xml, b"_", close)?;
    Some(&xml[underscore + 1..])
}

/// The 1-based line of byte `at` of `text` (its end when `at` is beyond it).
pub(crate) fn line_of(text: &[u8], at: usize) -> usize {
    1 + text[..at.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// The XML text before its `<AppendedData>` element (the whole text when it has none), where
/// every piece and array is declared: raw appended bytes could contain anything.
pub(crate) fn head(xml: &[u8]) -> &[u8] {
    &xml[..find(xml, b"<AppendedData", 0).unwrap_or(xml.len())]
}

pub(crate) fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|i| i + from)
}

fn rfind(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).rposition(|w| w == needle)
}

/// Standard padded base64, as VTK writes it.
fn encode(bytes: &[u8]) -> Vec<u8> {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD
        .encode(bytes)
        .into_bytes()
}
