//! Reading OpenStreetMap data: XML (`.osm`) with quick-xml and PBF (`.osm.pbf`) with
//! osmpbf, into one in-memory model of nodes, ways and relations with their tags.
//!
//! Problems that lose only one element (a node without coordinates, a tag without a key)
//! are warnings naming the file and line (XML) or element id (PBF), and reading goes on;
//! a file that cannot be parsed at all is an error saying where.

pub mod highway;
mod pbf;
mod xml;

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

/// A way: its node references in order and its tags.
#[derive(Clone, Debug, PartialEq)]
pub struct Way {
    /// OSM id.
    pub id: i64,
    /// Node ids, in order.
    pub refs: Vec<i64>,
    /// Tags (key, value), in file order.
    pub tags: Vec<(String, String)>,
}

impl Way {
    /// The value of tag `key`.
    pub fn tag(&self, key: &str) -> Option<&str> {
        tag(&self.tags, key)
    }
}

/// What a relation member is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemberKind {
    /// A node.
    Node,
    /// A way.
    Way,
    /// A relation.
    Relation,
}

/// A relation member.
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    /// Kind of the referenced element.
    pub kind: MemberKind,
    /// Its id.
    pub id: i64,
    /// Role (`left`, `right`, `from`, …), possibly empty.
    pub role: String,
}

/// A relation: members and tags.
#[derive(Clone, Debug, PartialEq)]
pub struct Relation {
    /// OSM id.
    pub id: i64,
    /// Members in order.
    pub members: Vec<Member>,
    /// Tags.
    pub tags: Vec<(String, String)>,
}

impl Relation {
    /// The value of tag `key`.
    pub fn tag(&self, key: &str) -> Option<&str> {
        tag(&self.tags, key)
    }
}

fn tag<'a>(tags: &'a [(String, String)], key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// Everything read from one file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OsmData {
    /// Node positions by id: (latitude, longitude), degrees.
    pub nodes: HashMap<i64, (f64, f64)>,
    /// Nodes read, counting any the file repeats.
    pub node_count: usize,
    /// Ways in file order.
    pub ways: Vec<Way>,
    /// Relations in file order.
    pub relations: Vec<Relation>,
    /// Elements skipped or read with a problem: `FILE:LINE: reason` (XML) or
    /// `FILE: node 42: reason` (PBF).
    pub warnings: Vec<String>,
}

impl OsmData {
    /// Ways with a `highway` tag.
    pub fn highway_ways(&self) -> impl Iterator<Item = &Way> {
        self.ways.iter().filter(|w| w.tag("highway").is_some())
    }

    /// Keep only what lies inside `bbox` (west, south, east, north, degrees): nodes
    /// outside are dropped and every way is cut into its runs of consecutive inside nodes
    /// (each run keeps the way's id and tags), so a road leaving and re-entering the box
    /// is not joined across the outside. A relation loses the members that are gone and
    /// the ways that were cut: a Lanelet2 lanelet with a cut bound is no longer a lanelet.
    pub fn clip(&mut self, bbox: [f64; 4]) {
        let [west, south, east, north] = bbox;
        self.nodes.retain(|_, &mut (lat, lon)| (south..=north).contains(&lat) && (west..=east).contains(&lon));
        let mut ways = Vec::with_capacity(self.ways.len());
        let mut whole = std::collections::HashSet::new();
        for way in self.ways.drain(..) {
            let runs: Vec<&[i64]> =
                way.refs.split(|r| !self.nodes.contains_key(r)).filter(|run| run.len() >= 2).collect();
            if let [run] = runs[..] {
                if run.len() == way.refs.len() {
                    whole.insert(way.id);
                }
            }
            ways.extend(runs.into_iter().map(|run| Way { id: way.id, refs: run.to_vec(), tags: way.tags.clone() }));
        }
        self.ways = ways;
        for relation in &mut self.relations {
            let nodes = &self.nodes;
            relation.members.retain(|m| match m.kind {
                MemberKind::Node => nodes.contains_key(&m.id),
                MemberKind::Way => whole.contains(&m.id),
                MemberKind::Relation => true,
            });
        }
    }
}

/// Why a file could not be read.
#[derive(Debug)]
pub enum OsmError {
    /// The file could not be opened or read.
    Io(String, std::io::Error),
    /// The file is not well-formed OSM XML / PBF; the string says where and why.
    Malformed(String),
}

impl fmt::Display for OsmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OsmError::Io(path, e) => write!(f, "{path}: {e}"),
            OsmError::Malformed(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for OsmError {}

/// Read an OSM file: PBF when the name ends in `.pbf`, XML otherwise.
pub fn read(path: &Path) -> Result<OsmData, OsmError> {
    let name = path.display().to_string();
    if name.ends_with(".pbf") {
        let bytes = std::fs::read(path).map_err(|e| OsmError::Io(name.clone(), e))?;
        pbf::parse(&bytes, &name)
    } else {
        let bytes = std::fs::read(path).map_err(|e| OsmError::Io(name.clone(), e))?;
        let text = String::from_utf8(bytes)
            .map_err(|e| OsmError::Malformed(format!("{name}: not UTF-8 at byte {}", e.utf8_error().valid_up_to())))?;
        xml::parse(&text, &name)
    }
}

pub use pbf::parse as parse_pbf;
pub use xml::parse as parse_xml;
