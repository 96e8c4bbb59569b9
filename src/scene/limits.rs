//! Limits on the shape of a scene document, checked before anything costly: the XML
//! parser's memory grows with the number of nodes and attributes, its duplicate-attribute
//! check is quadratic in the attributes of one element, and the scene walk recurses into
//! nested elements. Real Mitsuba scenes stay far below every limit here.

use glam::DVec3;
use roxmltree::{Document, Node};

/// Deepest element nesting accepted (`<scene>` is depth 1; real scenes reach about 6).
pub const MAX_DEPTH: usize = 64;
/// XML nodes (elements, text, comments) in one scene: a few hundred MB of parser memory.
pub const MAX_NODES: u32 = 4_000_000;
/// Attributes of one element (Mitsuba's elements have at most about five).
pub const MAX_ELEMENT_ATTRIBUTES: usize = 64;
/// Attributes in the whole document.
pub const MAX_ATTRIBUTES: usize = 4_000_000;

/// A problem found by [`prescan`]: the byte offset it is at and the message.
pub struct Rejected {
    pub offset: usize,
    pub message: String,
}

/// Counts the attributes of every start tag in one linear pass over the raw text
/// (before the parser sees it). Comments, CDATA, processing instructions and
/// declarations are skipped; `=` inside quoted values does not count. Malformed markup
/// is left for the parser to report.
pub fn prescan(text: &str) -> Result<(), Rejected> {
    let b = text.as_bytes();
    let mut total = 0usize;
    let mut i = 0usize;
    while let Some(rel) = text[i..].find('<') {
        let start = i + rel;
        let rest = &text[start..];
        let skip_to = |open: usize, close: &str| {
            rest[open..]
                .find(close)
                .map_or(b.len(), |p| start + open + p + close.len())
        };
        if rest.starts_with("<!--") {
            i = skip_to(4, "-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(9, "]]>");
        } else if rest.starts_with("<?") {
            i = skip_to(2, "?>");
        } else if rest.starts_with("<!") {
            i = skip_to(2, ">");
        } else {
            // A start or end tag: up to the first '>' outside quotes.
            let mut quote = None;
            let mut count = 0usize;
            let mut j = start + 1;
            while j < b.len() {
                let c = b[j];
                match quote {
                    Some(q) if c == q => quote = None,
                    Some(_) => {}
                    None if c == b'"' || c == b'\'' => quote = Some(c),
                    None if c == b'=' => count += 1,
                    None if c == b'>' => break,
                    None => {}
                }
                j += 1;
            }
            if count > MAX_ELEMENT_ATTRIBUTES {
                return Err(Rejected {
                    offset: start,
                    message: format!(
                        "an element with {count} attributes (at most {MAX_ELEMENT_ATTRIBUTES} are accepted)"
                    ),
                });
            }
            total += count;
            if total > MAX_ATTRIBUTES {
                return Err(Rejected {
                    offset: start,
                    message: format!(
                        "more than {MAX_ATTRIBUTES} attributes in the document (far beyond any real scene)"
                    ),
                });
            }
            i = j.min(b.len());
        }
        if i >= b.len() {
            break;
        }
    }
    Ok(())
}

/// The first element nested deeper than [`MAX_DEPTH`], in document order. Iterative:
/// one pass over the nodes with the depth of each remembered by node id.
pub fn too_deep<'a, 'i>(doc: &'a Document<'i>) -> Option<Node<'a, 'i>> {
    let mut depth: Vec<u32> = Vec::new();
    for node in doc.root().descendants() {
        let id = node.id().get_usize();
        let d = node.parent().map_or(0, |p| {
            depth.get(p.id().get_usize()).copied().unwrap_or(0) + 1
        });
        if depth.len() <= id {
            depth.resize(id + 1, 0);
        }
        depth[id] = d;
        if node.is_element() && d as usize > MAX_DEPTH {
            return Some(node);
        }
    }
    None
}

/// The largest world-space coordinate accepted. Geometry is single precision and its
/// arithmetic squares distances (edge cross products, sphere tests, 1/r^2 falloff), so
/// coordinates must stay far below sqrt(f32::MAX) ~ 1.8e19.
pub const MAX_COORDINATE: f64 = 1e15;

/// A world-space point that is not finite or lies beyond [`MAX_COORDINATE`].
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "world-space point {point} lies beyond +-{max:e} (single-precision geometry would overflow)",
    max = MAX_COORDINATE
)]
pub struct WorldPointError {
    pub point: DVec3,
}

/// A world-space point must be finite in single precision and within [`MAX_COORDINATE`].
pub fn check_world_point(p: DVec3) -> Result<(), WorldPointError> {
    if p.is_finite() && p.abs().max_element() <= MAX_COORDINATE {
        Ok(())
    } else {
        Err(WorldPointError { point: p })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prescan_counts_attributes_outside_quotes_comments_and_cdata() {
        assert!(
            prescan(r#"<a x="1" y='2=3'><!-- <b c="1" d="2"> --><![CDATA[ a=b=c ]]></a>"#).is_ok()
        );
        let many: String = (0..=MAX_ELEMENT_ATTRIBUTES)
            .map(|k| format!(" a{k}=\"\""))
            .collect();
        let text = format!("<?xml version=\"1.0\"?>\n<scene>\n<x{many}/></scene>");
        let e = prescan(&text).err().unwrap();
        assert_eq!(&text[e.offset..e.offset + 2], "<x");
        assert!(e.message.contains("attributes"), "{}", e.message);
        // Exactly at the limit is fine; quoted '=' and '>' do not count or end the tag.
        let ok: String = (0..MAX_ELEMENT_ATTRIBUTES)
            .map(|k| format!(" a{k}=\"=>\""))
            .collect();
        assert!(prescan(&format!("<x{ok}/>")).is_ok());
        // Unterminated markup is left to the parser.
        assert!(prescan("<a b=\"").is_ok() && prescan("<!-- ").is_ok() && prescan("<").is_ok());
    }

    #[test]
    fn depth_is_found_without_recursion() {
        let n = 100_000;
        let text = format!("{}{}", "<a>".repeat(n), "</a>".repeat(n));
        let doc = Document::parse(&text).unwrap();
        let node = too_deep(&doc).unwrap();
        // ancestors() counts the node itself and the document root.
        assert_eq!(node.ancestors().count(), MAX_DEPTH + 2);
        let ok = format!("{}{}", "<a>".repeat(MAX_DEPTH), "</a>".repeat(MAX_DEPTH));
        assert!(too_deep(&Document::parse(&ok).unwrap()).is_none());
    }
}
