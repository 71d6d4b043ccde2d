//! OSM PBF through the osmpbf crate.
//!
//! osmpbf returns errors for malformed blobs, but a few of its accessors `unwrap` on
//! corrupted protobuf enums; the decode runs under `catch_unwind` so that a corrupted
//! file is an error here, not a crash.

use std::panic::{catch_unwind, AssertUnwindSafe};

use osmpbf::{Element, ElementReader, RelMemberType};

use super::{Member, MemberKind, OsmData, OsmError, Relation, Way};

fn owned_tags<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Vec<(String, String)> {
    tags.map(|(k, v)| (k.to_owned(), v.to_owned())).collect()
}

fn add_node(data: &mut OsmData, name: &str, id: i64, lat: f64, lon: f64) {
    data.node_count += 1;
    if (-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon) {
        data.nodes.insert(id, (lat, lon));
    } else {
        data.warnings.push(format!("{name}: node {id} skipped: lat {lat} lon {lon} out of range"));
    }
}

/// Parse PBF bytes; `name` labels warnings and errors.
pub fn parse(bytes: &[u8], name: &str) -> Result<OsmData, OsmError> {
    let mut data = OsmData::default();
    let outcome = catch_unwind(AssertUnwindSafe(|| {
        ElementReader::new(bytes).for_each(|element| match element {
            Element::Node(n) => add_node(&mut data, name, n.id(), n.lat(), n.lon()),
            Element::DenseNode(n) => add_node(&mut data, name, n.id(), n.lat(), n.lon()),
            Element::Way(w) => data.ways.push(Way { id: w.id(), refs: w.refs().collect(), tags: owned_tags(w.tags()) }),
            Element::Relation(r) => {
                let mut members = Vec::new();
                for m in r.members() {
                    let kind = match m.member_type {
                        RelMemberType::Node => MemberKind::Node,
                        RelMemberType::Way => MemberKind::Way,
                        RelMemberType::Relation => MemberKind::Relation,
                    };
                    match m.role() {
                        Ok(role) => members.push(Member { kind, id: m.member_id, role: role.to_owned() }),
                        Err(e) => data.warnings.push(format!("{name}: relation {}: member skipped: {e}", r.id())),
                    }
                }
                data.relations.push(Relation { id: r.id(), members, tags: owned_tags(r.tags()) });
            }
        })
    }));
    match outcome {
        Ok(Ok(())) => Ok(data),
        Ok(Err(e)) => Err(OsmError::Malformed(format!("{name}: not a readable OSM PBF file: {e}"))),
        Err(_) => Err(OsmError::Malformed(format!("{name}: corrupted OSM PBF file (the PBF decoder gave up)"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn garbage_and_truncation_are_errors() {
        let e = parse(b"definitely not protobuf", "x.osm.pbf").expect_err("garbage").to_string();
        assert!(e.starts_with("x.osm.pbf:"), "{e}");
        assert!(parse(&[], "empty.osm.pbf").is_ok_and(|d| d.ways.is_empty()), "an empty file has no elements");
    }
}
