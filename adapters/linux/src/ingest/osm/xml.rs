//! OSM XML (`<osm><node/><way><nd/><tag/></way><relation><member/></relation></osm>`).

use std::collections::HashMap;

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

use super::{Member, MemberKind, OsmData, OsmError, Relation, Way};
use crate::{Error, Result};

/// 1-based line of byte offset `pos` in `text`.
fn line_of(text: &str, pos: u64) -> usize {
    let end = usize::try_from(pos).unwrap_or(usize::MAX).min(text.len());
    text.as_bytes()[..end].iter().filter(|&&b| b == b'\n').count() + 1
}

/// The element's attributes as (key, value) strings; a broken attribute is an error.
fn attributes(e: &BytesStart<'_>) -> Result<HashMap<String, String>> {
    let mut out = HashMap::new();
    for attr in e.attributes() {
        let attr = attr.map_err(Error::other)?;
        let key = attr.key.as_ref().to_owned();
        let value = attr.normalized_value(XmlVersion::Implicit1_0).map_err(Error::other)?;
        out.insert(key, value.into_owned());
    }
    Ok(out)
}

fn number<T: std::str::FromStr>(attrs: &HashMap<String, String>, key: &str) -> Result<T> {
    let text = attrs.get(key).ok_or_else(|| Error::invalid(format!("no `{key}`")))?;
    text.parse().map_err(|_| Error::invalid(format!("`{key}` is not a number: {text:?}")))
}

enum Open {
    None,
    Way(Way),
    Relation(Relation),
}

/// Parse OSM XML; `name` labels warnings and errors.
pub fn parse(text: &str, name: &str) -> Result<OsmData, OsmError> {
    let mut reader = Reader::from_str(text);
    let mut data = OsmData::default();
    let mut open = Open::None;
    let mut seen_osm = false;
    loop {
        let event = reader
            .read_event()
            .map_err(|e| OsmError::Malformed(format!("{name}:{}: {e}", line_of(text, reader.error_position()))))?;
        let at = || line_of(text, reader.buffer_position());
        let (element, is_empty) = match &event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(e) => {
                match (e.name().as_ref(), std::mem::replace(&mut open, Open::None)) {
                    ("way", Open::Way(way)) => data.ways.push(way),
                    ("relation", Open::Relation(relation)) => data.relations.push(relation),
                    (_, other) => open = other,
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let attrs = match attributes(element) {
            Ok(a) => a,
            Err(why) => {
                data.warnings.push(format!("{name}:{}: bad attribute: {why}", at()));
                continue;
            }
        };
        match element.name().as_ref() {
            "osm" => seen_osm = true,
            "node" => {
                data.node_count += 1;
                let parsed = (number::<i64>(&attrs, "id"), number::<f64>(&attrs, "lat"), number::<f64>(&attrs, "lon"));
                match parsed {
                    (Ok(id), Ok(lat), Ok(lon)) if (-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon) => {
                        data.nodes.insert(id, (lat, lon));
                    }
                    (Err(why), _, _) | (_, Err(why), _) | (_, _, Err(why)) => {
                        data.warnings.push(format!("{name}:{}: node skipped: {why}", at()));
                    }
                    (Ok(id), Ok(lat), Ok(lon)) => {
                        data.warnings
                            .push(format!("{name}:{}: node {id} skipped: lat {lat} lon {lon} out of range", at()));
                    }
                }
            }
            "way" => match number::<i64>(&attrs, "id") {
                Ok(id) => {
                    let way = Way { id, refs: Vec::new(), tags: Vec::new() };
                    if is_empty {
                        data.ways.push(way);
                    } else {
                        open = Open::Way(way);
                    }
                }
                Err(why) => data.warnings.push(format!("{name}:{}: way skipped: {why}", at())),
            },
            "relation" => match number::<i64>(&attrs, "id") {
                Ok(id) => {
                    let relation = Relation { id, members: Vec::new(), tags: Vec::new() };
                    if is_empty {
                        data.relations.push(relation);
                    } else {
                        open = Open::Relation(relation);
                    }
                }
                Err(why) => data.warnings.push(format!("{name}:{}: relation skipped: {why}", at())),
            },
            "nd" => match (&mut open, number::<i64>(&attrs, "ref")) {
                (Open::Way(way), Ok(r)) => way.refs.push(r),
                (Open::Way(way), Err(why)) => {
                    data.warnings.push(format!("{name}:{}: way {}: node reference skipped: {why}", at(), way.id));
                }
                _ => {}
            },
            "tag" => {
                let (Some(k), Some(v)) = (attrs.get("k"), attrs.get("v")) else {
                    data.warnings.push(format!("{name}:{}: tag without k or v skipped", at()));
                    continue;
                };
                match &mut open {
                    Open::Way(way) => way.tags.push((k.clone(), v.clone())),
                    Open::Relation(relation) => relation.tags.push((k.clone(), v.clone())),
                    Open::None => {} // node tags are not used
                }
            }
            "member" => {
                let Open::Relation(relation) = &mut open else { continue };
                let kind = match attrs.get("type").map(String::as_str) {
                    Some("node") => MemberKind::Node,
                    Some("way") => MemberKind::Way,
                    Some("relation") => MemberKind::Relation,
                    other => {
                        data.warnings.push(format!("{name}:{}: member of unknown type {other:?} skipped", at()));
                        continue;
                    }
                };
                match number::<i64>(&attrs, "ref") {
                    Ok(id) => {
                        relation.members.push(Member { kind, id, role: attrs.get("role").cloned().unwrap_or_default() })
                    }
                    Err(why) => data.warnings.push(format!("{name}:{}: member skipped: {why}", at())),
                }
            }
            _ => {}
        }
    }
    if !seen_osm {
        return Err(OsmError::Malformed(format!("{name}: no <osm> element: not an OSM XML file")));
    }
    match open {
        Open::None => Ok(data),
        Open::Way(w) => Err(OsmError::Malformed(format!("{name}: way {} is not closed (truncated file?)", w.id))),
        Open::Relation(r) => {
            Err(OsmError::Malformed(format!("{name}: relation {} is not closed (truncated file?)", r.id)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <node id="1" lat="60.0" lon="24.0"/>
  <node id="2" lat="60.001" lon="24.0"><tag k="highway" v="crossing"/></node>
  <node id="3" lat="95.0" lon="24.0"/>
  <node id="4" lon="24.0"/>
  <way id="10">
    <nd ref="1"/><nd ref="2"/><nd ref="99"/>
    <tag k="highway" v="residential"/><tag k="name" v="Mannerheimintie &amp; co"/>
  </way>
  <way id="11"/>
  <relation id="20">
    <member type="way" ref="10" role="left"/>
    <member type="area" ref="10" role="x"/>
    <tag k="type" v="lanelet"/>
  </relation>
</osm>
"#;

    #[test]
    fn reads_elements_tags_and_members_and_names_the_bad_lines() {
        let data = parse(SAMPLE, "t.osm").expect("parses");
        assert_eq!((data.node_count, data.nodes.len()), (4, 2));
        assert_eq!(data.ways.len(), 2);
        assert_eq!(data.ways[0].refs, [1, 2, 99]);
        assert_eq!(data.ways[0].tag("name"), Some("Mannerheimintie & co"));
        assert_eq!(data.relations[0].members.len(), 1);
        assert_eq!(data.relations[0].members[0].role, "left");
        assert_eq!(data.relations[0].tag("type"), Some("lanelet"));
        assert_eq!(data.highway_ways().count(), 1);
        let warnings = data.warnings.join("\n");
        assert!(warnings.contains("t.osm:5: node 3 skipped: lat 95"), "{warnings}");
        assert!(warnings.contains("t.osm:6: node skipped: no `lat`"), "{warnings}");
        assert!(warnings.contains("t.osm:14: member of unknown type"), "{warnings}");
    }

    #[test]
    fn truncated_and_foreign_files_are_errors() {
        let cut = &SAMPLE[..SAMPLE.find("</way>").expect("way")];
        let e = parse(cut, "cut.osm").expect_err("truncated").to_string();
        assert!(e.contains("way 10 is not closed"), "{e}");
        let e = parse("<html><body/></html>", "page.html").expect_err("not osm").to_string();
        assert!(e.contains("no <osm> element"), "{e}");
        let e = parse("<osm><node id=\"1\" lat=\"1\" lon=\"2\"></way></osm>", "bad.osm").expect_err("bad").to_string();
        assert!(e.starts_with("bad.osm:1:"), "{e}");
    }
}
