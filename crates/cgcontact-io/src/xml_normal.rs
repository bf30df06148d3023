//! Putting an XML VTK file into the one spelling that the byte-level passes read as XML does.
//!
//! The passes that run before vtkio (`lzma_arrays`, `raw_appended`, `block_headers`, the list of
//! declared arrays) find elements and attributes by searching bytes: the first `<VTKFile`, the
//! first `>` after a tag's start, `format="binary"` spelt out. XML allows other spellings of the
//! same document, which vtkio's parser (quick-xml) reads as XML: `<VTKFile>` inside a comment or a
//! processing instruction before the root, `>` inside an attribute value, a character reference
//! in a value (`format="&#98;inary"`). The block-header check then read the wrong element or
//! nothing, and a header claiming 100 GB reached vtkio, whose failed allocation aborted the
//! process. So before any of them runs, the file is tokenized here with quick-xml, the same
//! tokenizer vtkio uses, and rewritten where needed so that searching bytes finds what XML means:
//!
//! - comments and processing instructions (other than the leading XML declaration) are blanked,
//!   each byte but line ends made a space, so that lines keep their numbers;
//! - a start tag with an attribute value holding `&`, `<`, `>`, `"` or `'` is rewritten with every
//!   value decoded and escaped again, entities only for those five characters (`&#98;inary`
//!   becomes `binary`, `a>b` becomes `a&gt;b`), its line ends kept before its closing `>`;
//! - text holding a reference other than those five is decoded the same way;
//! - a `DOCTYPE` (it could declare entities) and `CDATA` sections (VTK writes neither) are refused,
//!   and so is what is not well-formed, an unknown entity included.
//!
//! In the result, `<` only starts markup (raw appended data aside, which this pass delimits
//! exactly as `raw_appended` does), `>` only ends it, and no attribute value or text holds a
//! quote, so a byte search can no longer be fooled by a value or a comment.
//!
//! String arrays (`<Array>` elements inside `PointData`, `CellData` and `FieldData`: VTK's
//! `vtkStringArray`, names or notes beside the data) are blanked whole, lines kept: vtkio reads
//! none, and a mesh needs none.
//!
//! The pass also refuses what no VTK file holds and what would cost time or memory out of
//! proportion to the file: an element nested deeper than [`MAX_DEPTH`] (vtkio's parser keeps every
//! open element: a 30 MB file of unclosed `<a>` took 765 MB), an element with more than
//! [`MAX_ATTRIBUTES`] attributes (checking them for duplicates is quadratic: 300,000 attributes
//! took minutes), a second root element, and anything but white space, comments and processing
//! instructions after `</VTKFile>`.

use std::ops::Range;

use quick_xml::events::{BytesStart, Event};

use crate::ErrorKind;

/// Deepest nesting of elements accepted. A VTU needs 7 (`VTKFile`, `UnstructuredGrid`, `Piece`,
/// `PointData`, `DataArray`, `InformationKey`, `Value`).
pub(crate) const MAX_DEPTH: usize = 32;

/// Most attributes one element may have. VTK's `DataArray` has about ten.
pub(crate) const MAX_ATTRIBUTES: usize = 256;

/// The five characters XML escapes; a value or text without them needs no decoding.
fn special(b: u8) -> bool {
    matches!(b, b'&' | b'<' | b'>' | b'"' | b'\'')
}

/// The file rewritten in the spelling described in the module docs, or `None` when it already is.
pub(crate) fn normalize(xml: &[u8]) -> Result<Option<Vec<u8>>, ErrorKind> {
    let mut pass = Pass {
        xml,
        edits: Vec::new(),
        open: Vec::new(),
        root_closed: false,
        seen_markup: false,
        skipping: None,
    };
    let start = if xml.starts_with(b"\xEF\xBB\xBF") {
        3
    } else {
        0
    };
    match pass.walk(start, xml.len())? {
        Stop::End => {}
        Stop::RawData(after_tag) => {
            // Raw appended data may hold any bytes: they run from the `_` to the last
            // `</AppendedData>` (as `raw_appended` reads them); tokenizing goes on from there.
            let underscore = after_tag
                + xml[after_tag..]
                    .iter()
                    .position(|b| !b.is_ascii_whitespace())
                    .unwrap_or(xml.len() - after_tag);
            if xml.get(underscore) != Some(&b'_') {
                return Err(pass.refuse(
                    underscore,
                    "raw <AppendedData> does not start with `_`".to_owned(),
                ));
            }
            const CLOSE: &[u8] = b"</AppendedData>";
            let close = xml[underscore..]
                .windows(CLOSE.len())
                .rposition(|w| w == CLOSE)
                .map(|i| underscore + i);
            match close {
                Some(close) => pass.tail(close)?,
                // Cut inside the data: the passes that read the arrays name the one cut.
                None => return pass.edited(),
            }
        }
    }
    if let Some((name, at)) = pass.open.last() {
        return Err(pass.refuse(
            *at,
            format!(
                "the file ends inside the <{}> element that starts here (truncated?)",
                shown(name)
            ),
        ));
    }
    if !pass.root_closed {
        return Err(ErrorKind::Vtk("XML VTK: no <VTKFile> element".to_owned()));
    }
    pass.edited()
}

/// Where a walk stopped.
enum Stop {
    /// At the end of its bytes.
    End,
    /// Right after a `<AppendedData encoding="raw">` start tag, at this byte.
    RawData(usize),
}

struct Pass<'a> {
    xml: &'a [u8],
    /// (bytes replaced, by what), in order.
    edits: Vec<(Range<usize>, Vec<u8>)>,
    /// Open elements: name and the byte where each starts.
    open: Vec<(Vec<u8>, usize)>,
    root_closed: bool,
    /// Whether anything but white space, the XML declaration, comments and processing
    /// instructions came before (the XML declaration must come first).
    seen_markup: bool,
    /// Inside an `<Array>` being blanked: the depth of `open` with it open, and where it starts.
    skipping: Option<(usize, usize)>,
}

impl Pass<'_> {
    /// The file with the edits made, or `None` when there are none.
    fn edited(self) -> Result<Option<Vec<u8>>, ErrorKind> {
        if self.edits.is_empty() {
            return Ok(None);
        }
        let mut out = Vec::with_capacity(self.xml.len());
        let mut copied = 0;
        for (range, text) in self.edits {
            out.extend_from_slice(&self.xml[copied..range.start]);
            out.extend_from_slice(&text);
            copied = range.end;
        }
        out.extend_from_slice(&self.xml[copied..]);
        Ok(Some(out))
    }

    fn line(&self, at: usize) -> usize {
        1 + self.xml[..at.min(self.xml.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    fn refuse(&self, at: usize, what: String) -> ErrorKind {
        ErrorKind::Vtk(crate::one_line(&format!(
            "XML VTK: line {}, byte {at}: {what}",
            self.line(at)
        )))
    }

    /// Tokenize `xml[from..to]`, with the elements open in `self.open` (the walk after raw
    /// appended data goes on inside the elements open before them).
    fn walk(&mut self, from: usize, to: usize) -> Result<Stop, ErrorKind> {
        let mut reader = quick_xml::Reader::from_reader(&self.xml[from..to]);
        let config = reader.config_mut();
        // End tags are matched here, with messages that name both elements.
        config.check_end_names = false;
        config.check_comments = true;
        loop {
            let at = from + usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
            let event = match reader.read_event() {
                Ok(event) => event,
                Err(e) => {
                    let place =
                        from + usize::try_from(reader.error_position()).unwrap_or(usize::MAX);
                    return Err(self.refuse(place, format!("not well-formed XML ({e})")));
                }
            };
            let end = from + usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
            match event {
                Event::Eof => return Ok(Stop::End),
                Event::Decl(_) if !self.seen_markup && self.open.is_empty() => {}
                Event::Decl(_) => {
                    return Err(self.refuse(at, "an XML declaration after the start".to_owned()));
                }
                Event::Comment(_) | Event::PI(_) if self.skipping.is_some() => {}
                Event::Comment(_) | Event::PI(_) => self.blank(at..end),
                Event::DocType(_) => {
                    return Err(self.refuse(
                        at,
                        "a DOCTYPE declaration (VTK files have none; it could define entities)"
                            .to_owned(),
                    ));
                }
                Event::CData(_) => {
                    return Err(self.refuse(at, "a CDATA section (VTK files have none)".to_owned()));
                }
                Event::Text(_) if self.skipping.is_some() => {}
                Event::Text(text) => {
                    if self.open.is_empty() {
                        if !text.iter().all(u8::is_ascii_whitespace) {
                            let what = if self.root_closed {
                                "content after </VTKFile>"
                            } else {
                                "text before the <VTKFile> element"
                            };
                            return Err(self.refuse(
                                at,
                                format!("{what}: {}", crate::excerpt(text.trim_ascii(), 40)),
                            ));
                        }
                        continue;
                    }
                    if text.iter().any(|&b| special(b)) {
                        let normal = self.normal(&text, at, "text")?;
                        if normal.as_bytes() != &*text {
                            self.edits.push((at..end, normal.into_bytes()));
                        }
                    }
                }
                Event::Start(ref tag) | Event::Empty(ref tag) => {
                    self.seen_markup = true;
                    let empty = matches!(event, Event::Empty(_));
                    let string_array = tag.name().as_ref() == b"Array"
                        && self.open.last().is_some_and(|(parent, _)| {
                            matches!(parent.as_slice(), b"PointData" | b"CellData" | b"FieldData")
                        });
                    if self.skipping.is_some() || string_array {
                        // An `<Array>` (VTK's element for string and variant arrays: names,
                        // notes) holds nothing a mesh needs and vtkio reads none: blanked
                        // whole, from its start tag to its end tag.
                        if self.open.len() >= MAX_DEPTH {
                            return Err(
                                self.refuse(at, format!("elements nested deeper than {MAX_DEPTH}"))
                            );
                        }
                        if empty {
                            if self.skipping.is_none() {
                                self.blank(at..end);
                            }
                        } else {
                            self.open.push((tag.name().as_ref().to_vec(), at));
                            if self.skipping.is_none() {
                                self.skipping = Some((self.open.len(), at));
                            }
                        }
                        continue;
                    }
                    self.element(tag, at..end, empty)?;
                    if empty && self.open.is_empty() {
                        self.root_closed = true;
                    }
                    if !empty {
                        self.open.push((tag.name().as_ref().to_vec(), at));
                        let raw = tag.name().as_ref() == b"AppendedData"
                            && attribute_value(tag, b"encoding").as_deref() == Some(b"raw");
                        if raw {
                            return Ok(Stop::RawData(end));
                        }
                    }
                }
                Event::End(tag) => {
                    // A mismatched end tag is left to vtkio's parser, which refuses it, so that
                    // `check_xml_arrays` names a corrupt start tag first.
                    if self.open.pop().is_none() {
                        return Err(self.refuse(
                            at,
                            format!("</{}> closes no element", shown(tag.name().as_ref())),
                        ));
                    }
                    if let Some((depth, start)) = self.skipping
                        && self.open.len() < depth
                    {
                        self.skipping = None;
                        self.blank(start..end);
                    }
                    if self.open.is_empty() {
                        self.root_closed = true;
                    }
                }
            }
        }
    }

    /// After raw appended data, from its `</AppendedData>`: only the end tags of the elements
    /// still open, white space, comments and processing instructions. (quick-xml cannot start
    /// there: it refuses end tags whose start it has not read.)
    fn tail(&mut self, mut at: usize) -> Result<(), ErrorKind> {
        let xml = self.xml;
        loop {
            at += xml[at..]
                .iter()
                .position(|b| !b.is_ascii_whitespace())
                .unwrap_or(xml.len() - at);
            let rest = &xml[at..];
            if rest.is_empty() {
                return Ok(());
            }
            let markup = |open: &[u8], close: &[u8]| {
                rest.starts_with(open)
                    .then(|| crate::raw_appended::find(rest, close, open.len()))
                    .flatten()
                    .map(|end| end + close.len())
            };
            if let Some(length) = markup(b"<!--", b"-->").or_else(|| markup(b"<?", b"?>")) {
                self.blank(at..at + length);
                at += length;
                continue;
            }
            let end_tag = rest.strip_prefix(b"</").and_then(|name| {
                let length = name.iter().position(|&b| b == b'>')?;
                Some((name[..length].trim_ascii_end(), length + 3))
            });
            let Some((name, length)) = end_tag else {
                let what = if self.open.is_empty() {
                    "content after </VTKFile>"
                } else {
                    "content after the raw appended data"
                };
                return Err(self.refuse(at, format!("{what}: {}", crate::excerpt(rest, 40))));
            };
            match self.open.pop() {
                // A mismatched end tag is left to vtkio's parser, as above.
                Some(_) => {}
                None => {
                    return Err(
                        self.refuse(at, format!("content after </VTKFile>: </{}>", shown(name)))
                    );
                }
            }
            if self.open.is_empty() {
                self.root_closed = true;
            }
            at += length;
        }
    }

    /// Check one start tag and rewrite it if its attributes need it.
    fn element(
        &mut self,
        tag: &BytesStart,
        span: Range<usize>,
        empty: bool,
    ) -> Result<(), ErrorKind> {
        let name = tag.name().as_ref().to_vec();
        let shown = shown(&name);
        if self.open.is_empty() {
            if self.root_closed {
                return Err(self.refuse(
                    span.start,
                    format!("content after </VTKFile>: a second root element <{shown}>"),
                ));
            }
            if name != b"VTKFile" {
                return Err(self.refuse(
                    span.start,
                    format!("the root element is <{shown}>, not <VTKFile>"),
                ));
            }
        }
        if self.open.len() >= MAX_DEPTH {
            return Err(self.refuse(
                span.start,
                format!(
                    "<{shown}> is nested {} elements deep, deeper than the {MAX_DEPTH} a VTK file \
                     could need (unclosed elements?)",
                    self.open.len() + 1
                ),
            ));
        }
        // Counted without checks first: the check for duplicates is quadratic in their number.
        let count = tag.attributes().with_checks(false).count();
        if count > MAX_ATTRIBUTES {
            return Err(self.refuse(
                span.start,
                format!(
                    "<{shown}> has {count} attributes, more than the {MAX_ATTRIBUTES} accepted"
                ),
            ));
        }
        let mut rewrite = false;
        let mut attributes = Vec::with_capacity(count);
        for attribute in tag.attributes() {
            let attribute = attribute.map_err(|e| {
                self.refuse(
                    span.start,
                    format!("<{shown}>: a malformed attribute ({e})"),
                )
            })?;
            let key = attribute.key.as_ref().to_vec();
            let raw = attribute.value.as_ref();
            let value = if raw.iter().any(|&b| special(b)) {
                let what = format!("the {} attribute of <{shown}>", self::shown(&key));
                let normal = self.normal(raw, span.start, &what)?;
                rewrite |= normal.as_bytes() != raw;
                normal.into_bytes()
            } else {
                raw.to_vec()
            };
            attributes.push((key, value));
        }
        // Quotes inside a value are escaped whatever they were: the tag keeps its quotes as they
        // are unless it is rewritten (then all are `"`).
        if rewrite {
            let mut text = b"<".to_vec();
            text.extend_from_slice(&name);
            for (key, value) in &attributes {
                text.push(b' ');
                text.extend_from_slice(key);
                text.extend_from_slice(b"=\"");
                text.extend_from_slice(value);
                text.push(b'"');
            }
            let line_ends = self.xml[span.clone()].iter().filter(|&&b| b == b'\n');
            text.extend(line_ends.copied());
            text.extend_from_slice(if empty { b"/>" } else { b">" });
            self.edits.push((span, text));
        }
        Ok(())
    }

    /// `raw` decoded and escaped again: entities only for `& < > " '`.
    fn normal(&self, raw: &[u8], at: usize, what: &str) -> Result<String, ErrorKind> {
        let text = std::str::from_utf8(raw)
            .map_err(|_| self.refuse(at, format!("{what} is not UTF-8 text")))?;
        let decoded = quick_xml::escape::unescape(text)
            .map_err(|e| self.refuse(at, format!("{what}: {e}")))?;
        Ok(quick_xml::escape::escape(decoded.as_ref()).into_owned())
    }

    /// Blank a comment or processing instruction, keeping its line ends.
    fn blank(&mut self, span: Range<usize>) {
        let text = self.xml[span.clone()]
            .iter()
            .map(|&b| if b == b'\n' || b == b'\r' { b } else { b' ' })
            .collect();
        self.edits.push((span, text));
    }
}

/// An element or attribute name in a message (cut, control characters escaped).
fn shown(name: &[u8]) -> String {
    let quoted = crate::excerpt(name, 40);
    quoted.trim_matches('`').to_owned()
}

/// An attribute's decoded value (`None` when absent or malformed).
fn attribute_value(tag: &BytesStart, name: &[u8]) -> Option<Vec<u8>> {
    let attribute = tag.try_get_attribute(name).ok()??;
    let value = attribute.unescape_value().ok()?;
    Some(value.as_bytes().to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normal(xml: &str) -> String {
        let out = normalize(xml.as_bytes()).unwrap();
        String::from_utf8(out.unwrap_or_else(|| xml.as_bytes().to_vec())).unwrap()
    }

    /// VTK writes string arrays (`vtkStringArray`: names, notes) as `<Array>` elements, which
    /// vtkio cannot read and `check_xml_arrays` refused as corrupt tags: they are blanked whole,
    /// lines kept, nested elements and comments within them included.
    #[test]
    fn string_arrays_in_data_sections_are_blanked_whole() {
        let xml = "<VTKFile><U><Piece><PointData>\n<Array type=\"String\" Name=\"n\">\n<!-- c -->a &amp; b\n\
                   <InformationKey><Value/></InformationKey></Array><DataArray/>\n</PointData>\n\
                   <FieldData><Array Name=\"e\"/></FieldData></Piece></U></VTKFile>";
        let out = normal(xml);
        assert_eq!(out.lines().count(), xml.lines().count());
        assert!(
            !out.contains("Array type") && !out.contains("Array Name"),
            "{out}"
        );
        assert!(!out.contains("Value") && !out.contains("&amp;"), "{out}");
        assert!(
            out.contains("<PointData>") && out.contains("<DataArray/>"),
            "{out}"
        );
        assert!(
            out.contains("<FieldData>") && out.contains("</FieldData>"),
            "{out}"
        );
        // Outside the data sections, `<Array>` is no string array: left to the later checks.
        assert!(normal("<VTKFile><Array/></VTKFile>").contains("<Array/>"));
    }

    #[test]
    fn other_spellings_become_the_plain_one() {
        assert_eq!(
            normal("<!-- <VTKFile> -->\n<VTKFile a=\"&#98;\"/>"),
            "                  \n<VTKFile a=\"b\"/>"
        );
        assert_eq!(
            normal("<?pi <VTKFile>?><VTKFile x='>'\n y=\"1\"></VTKFile>"),
            "                <VTKFile x=\"&gt;\" y=\"1\"\n></VTKFile>"
        );
        assert_eq!(
            normal("<VTKFile><A>x&#65;y</A></VTKFile>"),
            "<VTKFile><A>xAy</A></VTKFile>"
        );
        // Already plain: nothing copied.
        let plain = "<?xml version=\"1.0\"?>\n<VTKFile a=\"x&amp;y\">t&lt;</VTKFile>\n";
        assert!(normalize(plain.as_bytes()).unwrap().is_none());
    }

    #[test]
    fn what_no_vtk_file_holds_is_refused() {
        for (xml, expected) in [
            ("<VTKFile></VTKFile><VTKFile/>", "second root"),
            ("<VTKFile></VTKFile>junk", "content after </VTKFile>"),
            ("<!DOCTYPE x><VTKFile/>", "DOCTYPE"),
            ("<VTKFile><![CDATA[x]]></VTKFile>", "CDATA"),
            ("<VTKFile a=\"&bogus;\"/>", "bogus"),
            ("<Other/>", "not <VTKFile>"),
            ("<VTKFile><A>", "ends inside the <A>"),
        ] {
            let message = normalize(xml.as_bytes()).unwrap_err().to_string();
            assert!(message.contains(expected), "{xml}: {message}");
        }
    }
}
