//! A map tile's roads as ASAM OpenDRIVE 1.7 (`docs/openscenario.md`): the road network
//! CARLA, esmini and the ASAM tool chain drive on, and the `.xodr` an OpenSCENARIO export
//! names.
//!
//! * **Roads**: one per roadblock of [`super::road`] (the tile's lanes side by side in one
//!   direction, between junctions). The reference line is the leftmost lane's centreline,
//!   fitted with lines and arcs ([`super::plan_view`]); a lane offset of half that lane's width
//!   puts the centre lane on its left edge, and every lane is a right lane (driving along the
//!   reference line, right-hand traffic) of its tile width.
//! * **Junctions**: every connector of [`super::road`] is a connecting road of one lane whose
//!   width goes smoothly from the lane it leaves to the lane it enters, from exactly where the
//!   one ends to where the other begins; the connectors that share a road's end or start are
//!   one junction, with a connection and lane link each.
//! * **Geo-reference**: the UTM zone of the map's origin (`<geoReference>`, PROJ), less the
//!   origin's UTM coordinates (`<offset>`: projected = local + offset), the frame of the
//!   CommonRoad export.
//!
//! The tile's lanes carry no heights: the roads are flat (no elevation profile).

use std::fmt::Write as _;

use super::junctions::DisjointSets;
use super::plan_view::PlanView;
use super::projection::Projection;
use super::road::Road;
use dash2sim_linux::geometry::{segment_distance, Line};
use dash2sim_linux::{Error, Result};

/// Samples along a lane when measuring it against the tile, m apart.
const SAMPLE_M: f64 = 0.25;

/// A tile's roads as OpenDRIVE.
#[derive(Clone, Debug)]
pub struct OpenDrive {
    /// The `.xodr` document.
    pub xodr: String,
    /// Roads (roadblocks).
    pub roads: usize,
    /// Connecting roads in junctions.
    pub connecting_roads: usize,
    /// Junctions.
    pub junctions: usize,
    /// Lanes of the roads (not counting connecting roads').
    pub lanes: usize,
    /// The largest distance between a lane's centre in the `.xodr` and the tile's, m (both
    /// ways: from every point of the one to the other).
    pub worst_centre_m: f64,
    /// The same for connecting roads against the connectors' curves, m.
    pub worst_connector_m: f64,
    /// EPSG code of the projected frame.
    pub epsg: i32,
    /// The projected coordinates of the local frame's origin (the `<offset>`), m.
    pub offset: (f64, f64),
}

/// One road of the document: its reference line and its lanes' widths, left to right.
struct RoadLine {
    plan: PlanView,
    widths: Vec<f64>,
    /// The road's pieces, left to right.
    pieces: Vec<usize>,
}

impl RoadLine {
    /// The lateral position of lane `k`'s centre (0 = leftmost), m to the left of the
    /// reference line.
    fn centre_t(&self, k: usize) -> f64 {
        let first = self.widths.first().copied().unwrap_or(0.0);
        0.5 * first - self.widths[..k].iter().sum::<f64>() - 0.5 * self.widths[k]
    }
}

/// A connecting road: the lane it leaves and the lane it enters (road, lane from the left),
/// its reference line, the two lanes' widths.
struct Connecting {
    from: (usize, usize),
    to: (usize, usize),
    plan: PlanView,
    widths: (f64, f64),
}

/// The roads of a document, before it is written.
struct Network {
    /// A road per roadblock (`None`: none of its lanes is long enough to draw).
    lines: Vec<Option<RoadLine>>,
    connecting: Vec<Connecting>,
    /// Each connecting road's junction (0…).
    junction_of: Vec<usize>,
    junctions: usize,
}

impl Network {
    fn road_id(&self, block: usize) -> usize {
        block + 1
    }

    fn connecting_id(&self, k: usize) -> usize {
        self.lines.len() + 1 + k
    }

    fn junction_id(&self, j: usize) -> usize {
        self.lines.len() + self.connecting.len() + 1 + j
    }
}

/// `road` (in `projection`'s frame) as an OpenDRIVE document named `name`. Errors for a
/// road with no lane long enough to draw.
pub fn opendrive(road: &Road, projection: &Projection, name: &str) -> Result<OpenDrive> {
    let offset = projection.project(&[(0.0, 0.0, 0.0)]).first().copied().unwrap_or_default();
    let (lines, lane_of, worst_centre_m) = roads(road, offset);
    if lines.iter().all(Option::is_none) {
        return Err(Error::invalid("the map has no lane long enough to draw as an OpenDRIVE road"));
    }
    let (connecting, worst_connector_m) = connecting_roads(road, &lines, &lane_of, offset);
    let (junction_of, junctions) = junctions(&connecting);
    let network = Network { lines, connecting, junction_of, junctions };
    let mut x = header_xml(road, projection, offset, name);
    let lanes = roads_xml(&mut x, &network, road);
    junctions_xml(&mut x, &network);
    x.push_str("</OpenDRIVE>\n");
    Ok(OpenDrive {
        xodr: x,
        roads: network.lines.iter().flatten().count(),
        connecting_roads: network.connecting.len(),
        junctions: network.junctions,
        lanes,
        worst_centre_m,
        worst_connector_m,
        epsg: projection.epsg(),
        offset,
    })
}

/// A road per roadblock, its pieces left to right; where each piece is (road, lane from the
/// left); the largest distance of a lane's drawn centre from the tile's.
fn roads(road: &Road, offset: (f64, f64)) -> (Vec<Option<RoadLine>>, Vec<(usize, usize)>, f64) {
    let local = |line: &[(f64, f64)]| local(line, offset);
    let blocks = road.pieces.iter().map(|p| p.roadblock + 1).max().unwrap_or(0);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); blocks];
    for (i, p) in road.pieces.iter().enumerate() {
        members[p.roadblock].push(i);
    }
    let mut lines: Vec<Option<RoadLine>> = Vec::with_capacity(blocks);
    let mut lane_of = vec![(0, 0); road.pieces.len()];
    let mut worst_centre_m: f64 = 0.0;
    for (b, pieces) in members.iter_mut().enumerate() {
        pieces.sort_by_key(|&i| road.pieces[i].lane_index);
        for (k, &i) in pieces.iter().enumerate() {
            lane_of[i] = (b, k);
        }
        let Some(plan) = pieces.first().and_then(|&i| PlanView::fit(&local(&road.pieces[i].centre))) else {
            lines.push(None);
            continue;
        };
        let line =
            RoadLine { plan, widths: pieces.iter().map(|&i| road.pieces[i].width).collect(), pieces: pieces.clone() };
        for (k, &i) in pieces.iter().enumerate() {
            let drawn = sample(&line.plan, line.centre_t(k), line.centre_t(k));
            worst_centre_m = worst_centre_m.max(hausdorff(&drawn, &local(&road.pieces[i].centre)));
        }
        lines.push(Some(line));
    }
    (lines, lane_of, worst_centre_m)
}

/// A connecting road per connector between two drawn roads: from exactly where the lane it
/// leaves ends to where the one it enters begins, along those roads' headings there (linked
/// lanes' borders meet only if the headings do); the largest distance from its curve.
fn connecting_roads(
    road: &Road,
    lines: &[Option<RoadLine>],
    lane_of: &[(usize, usize)],
    offset: (f64, f64),
) -> (Vec<Connecting>, f64) {
    let local = |line: &[(f64, f64)]| local(line, offset);
    let mut connecting = Vec::new();
    let mut worst_connector_m: f64 = 0.0;
    for c in &road.connectors {
        let (from, to) = (lane_of[c.from], lane_of[c.to]);
        let (Some(a), Some(b)) = (&lines[from.0], &lines[to.0]) else { continue };
        let mut centre = local(&c.centre);
        let (start, end) = (a.plan.offset(a.plan.length(), a.centre_t(from.1)), b.plan.offset(0.0, b.centre_t(to.1)));
        if let Some(first) = centre.first_mut() {
            *first = start;
        }
        if let Some(last) = centre.last_mut() {
            *last = end;
        }
        let (start_heading, end_heading) = (a.plan.at(a.plan.length()).2, b.plan.at(0.0).2);
        let Some(plan) = PlanView::fit_between(&centre, start_heading, end_heading) else { continue };
        worst_connector_m = worst_connector_m.max(hausdorff(&sample(&plan, 0.0, 0.0), &centre));
        connecting.push(Connecting { from, to, plan, widths: (a.widths[from.1], b.widths[to.1]) });
    }
    (connecting, worst_connector_m)
}

/// Junctions: connecting roads that share the end of the road they leave or the start of
/// the road they enter are one. Each connecting road's junction (numbered by its first
/// connecting road), and how many there are.
fn junctions(connecting: &[Connecting]) -> (Vec<usize>, usize) {
    let mut sets = DisjointSets::new(connecting.len());
    let mut first_from = std::collections::BTreeMap::new();
    let mut first_to = std::collections::BTreeMap::new();
    for (k, c) in connecting.iter().enumerate() {
        for (first, key) in [(&mut first_from, c.from.0), (&mut first_to, c.to.0)] {
            match first.get(&key) {
                Some(&j) => sets.join(j, k),
                None => {
                    first.insert(key, k);
                }
            }
        }
    }
    // A set's root is its first member: sorted roots number the junctions in that order.
    let roots: std::collections::BTreeSet<usize> = (0..connecting.len()).map(|k| sets.root(k)).collect();
    let roots: Vec<usize> = roots.into_iter().collect();
    let junction_of = (0..connecting.len())
        .map(|k| {
            let root = sets.root(k);
            roots.iter().position(|&r| r == root).unwrap_or(0)
        })
        .collect();
    (junction_of, roots.len())
}

/// The document's start: the header with its bounds and geo-reference.
fn header_xml(road: &Road, projection: &Projection, offset: (f64, f64), name: &str) -> String {
    let mut bounds = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for p in road.pieces.iter().flat_map(|p| p.left.iter().chain(&p.right)) {
        let (x, y) = (p.0 - offset.0, p.1 - offset.1);
        bounds = [bounds[0].min(x), bounds[1].min(y), bounds[2].max(x), bounds[3].max(y)];
    }
    let south = if projection.north { "" } else { " +south" };
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<OpenDRIVE>\n  <header revMajor=\"1\" revMinor=\"7\" name=\"{}\" version=\"1.00\" north=\"{:.3}\" south=\"{:.3}\" east=\"{:.3}\" west=\"{:.3}\" vendor=\"dash2sim\">\n    <geoReference><![CDATA[+proj=utm +zone={}{south} +datum=WGS84 +units=m +no_defs]]></geoReference>\n    <offset x=\"{:.3}\" y=\"{:.3}\" z=\"0\" hdg=\"0\"/>\n  </header>\n",
        super::xml_escape(name),
        bounds[3],
        bounds[1],
        bounds[2],
        bounds[0],
        projection.zone,
        offset.0,
        offset.1
    )
}

/// Every road, then every connecting road, into `x`; the roads' lanes counted.
fn roads_xml(x: &mut String, n: &Network, road: &Road) -> usize {
    let mut lanes = 0;
    for (b, line) in n.lines.iter().enumerate() {
        let Some(line) = line else { continue };
        let mut link = String::new();
        if let Some(k) = n.connecting.iter().position(|c| c.to.0 == b) {
            let _ = writeln!(
                link,
                "      <predecessor elementType=\"junction\" elementId=\"{}\"/>",
                n.junction_id(n.junction_of[k])
            );
        }
        if let Some(k) = n.connecting.iter().position(|c| c.from.0 == b) {
            let _ = writeln!(
                link,
                "      <successor elementType=\"junction\" elementId=\"{}\"/>",
                n.junction_id(n.junction_of[k])
            );
        }
        let speed = line.pieces.first().and_then(|&i| road.pieces[i].speed_limit);
        road_xml(x, n.road_id(b), "-1", &line.plan, &link, speed, |x| {
            let _ =
                writeln!(x, "        <laneOffset s=\"0\" a=\"{:.4}\" b=\"0\" c=\"0\" d=\"0\"/>", 0.5 * line.widths[0]);
            x.push_str("        <laneSection s=\"0\">\n          <center>\n            <lane id=\"0\" type=\"none\" level=\"false\"/>\n          </center>\n          <right>\n");
            for (k, w) in line.widths.iter().enumerate() {
                let _ = writeln!(
                    x,
                    "            <lane id=\"-{}\" type=\"driving\" level=\"false\">\n              <width sOffset=\"0\" a=\"{w:.4}\" b=\"0\" c=\"0\" d=\"0\"/>\n            </lane>",
                    k + 1
                );
            }
            x.push_str("          </right>\n        </laneSection>\n");
        });
        lanes += line.widths.len();
    }
    for (k, c) in n.connecting.iter().enumerate() {
        connecting_road_xml(x, n, road, k, c);
    }
    lanes
}

/// Connecting road `k` (`c`): linked to the road it leaves and the road it enters, its one
/// lane's width going from the one lane's to the other's.
fn connecting_road_xml(x: &mut String, n: &Network, road: &Road, k: usize, c: &Connecting) {
    let link = format!(
        "      <predecessor elementType=\"road\" elementId=\"{}\" contactPoint=\"end\"/>\n      <successor elementType=\"road\" elementId=\"{}\" contactPoint=\"start\"/>\n",
        n.road_id(c.from.0),
        n.road_id(c.to.0)
    );
    let junction = n.junction_id(n.junction_of[k]).to_string();
    let speed = n.lines[c.from.0].as_ref().and_then(|l| l.pieces.first()).and_then(|&i| road.pieces[i].speed_limit);
    // The width from the lane left to the lane entered, flat at both ends: a cubic.
    let (w0, w1, l) = (c.widths.0, c.widths.1, c.plan.length());
    let (cw, dw) = (3.0 * (w1 - w0) / (l * l), -2.0 * (w1 - w0) / (l * l * l));
    road_xml(x, n.connecting_id(k), &junction, &c.plan, &link, speed, |x| {
        let _ = writeln!(
            x,
            "        <laneOffset s=\"0\" a=\"{:.4}\" b=\"0\" c=\"{:.6e}\" d=\"{:.6e}\"/>",
            0.5 * w0,
            0.5 * cw,
            0.5 * dw
        );
        let _ = writeln!(
            x,
            "        <laneSection s=\"0\">\n          <center>\n            <lane id=\"0\" type=\"none\" level=\"false\"/>\n          </center>\n          <right>\n            <lane id=\"-1\" type=\"driving\" level=\"false\">\n              <link>\n                <predecessor id=\"-{}\"/>\n                <successor id=\"-{}\"/>\n              </link>\n              <width sOffset=\"0\" a=\"{w0:.4}\" b=\"0\" c=\"{cw:.6e}\" d=\"{dw:.6e}\"/>\n            </lane>\n          </right>\n        </laneSection>",
            c.from.1 + 1,
            c.to.1 + 1
        );
    });
}

/// Every junction: a connection per connecting road, with its lane link.
fn junctions_xml(x: &mut String, n: &Network) {
    for j in 0..n.junctions {
        let _ = writeln!(x, "  <junction id=\"{}\" name=\"junction {}\">", n.junction_id(j), j + 1);
        for (k, c) in n.connecting.iter().enumerate().filter(|&(k, _)| n.junction_of[k] == j) {
            let _ = writeln!(
                x,
                "    <connection id=\"{k}\" incomingRoad=\"{}\" connectingRoad=\"{}\" contactPoint=\"start\">\n      <laneLink from=\"-{}\" to=\"-1\"/>\n    </connection>",
                n.road_id(c.from.0),
                n.connecting_id(k),
                c.from.1 + 1
            );
        }
        x.push_str("  </junction>\n");
    }
}

/// One `<road>`: its links, type, plan view and the lanes `lanes` writes.
fn road_xml(
    x: &mut String,
    id: usize,
    junction: &str,
    plan: &PlanView,
    link: &str,
    speed: Option<f64>,
    lanes: impl FnOnce(&mut String),
) {
    let _ = writeln!(x, "  <road id=\"{id}\" junction=\"{junction}\" length=\"{:.6}\" rule=\"RHT\">", plan.length());
    if link.is_empty() {
        x.push_str("    <link/>\n");
    } else {
        let _ = write!(x, "    <link>\n{link}    </link>\n");
    }
    match speed {
        Some(v) => {
            let _ = writeln!(
                x,
                "    <type s=\"0\" type=\"town\">\n      <speed max=\"{v:.2}\" unit=\"m/s\"/>\n    </type>"
            );
        }
        None => x.push_str("    <type s=\"0\" type=\"town\"/>\n"),
    }
    x.push_str("    <planView>\n");
    for e in &plan.elements {
        let _ = write!(
            x,
            "      <geometry s=\"{:.6}\" x=\"{:.6}\" y=\"{:.6}\" hdg=\"{:.9}\" length=\"{:.6}\">",
            e.s, e.x, e.y, e.heading, e.length
        );
        if e.curvature == 0.0 {
            x.push_str("<line/>");
        } else {
            let _ = write!(x, "<arc curvature=\"{:.9}\"/>", e.curvature);
        }
        x.push_str("</geometry>\n");
    }
    x.push_str("    </planView>\n    <lanes>\n");
    lanes(x);
    x.push_str("    </lanes>\n  </road>\n");
}

/// `line` in the local frame: less the projected coordinates of its origin, `offset`.
fn local(line: &[(f64, f64)], offset: (f64, f64)) -> Line {
    line.iter().map(|p| (p.0 - offset.0, p.1 - offset.1)).collect()
}

/// Points along `plan` every [`SAMPLE_M`], `t_start` to the left at its start going linearly
/// to `t_end` at its end.
fn sample(plan: &PlanView, t_start: f64, t_end: f64) -> Line {
    let l = plan.length();
    let n = (l / SAMPLE_M).ceil().max(1.0) as usize;
    (0..=n)
        .map(|i| {
            let f = i as f64 / n as f64;
            plan.offset(l * f, t_start + (t_end - t_start) * f)
        })
        .collect()
}

/// The largest distance from a point of either polyline to the other.
fn hausdorff(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let one_way = |from: &[(f64, f64)], to: &[(f64, f64)]| {
        from.iter()
            .map(|&p| to.windows(2).map(|w| segment_distance(p, w[0], w[1]).0).fold(f64::INFINITY, f64::min))
            .fold(0.0, f64::max)
    };
    one_way(a, b).max(one_way(b, a))
}

/// `dash2sim map export MAP --opendrive F.xodr`: the roads of a map tile or an OpenStreetMap
/// file (built into a tile around its own centre) written as OpenDRIVE to `out` (under a
/// temporary name, renamed once whole).
pub fn write(map: &std::path::Path, out: &std::path::Path) -> Result<OpenDrive> {
    let tile = super::map_tile(map, None)?;
    let view = dash2sim_core::map::MapView::parse(&tile).map_err(|e| Error::refused("map", e))?;
    let [lat, lon, h] = view.header().origin;
    let origin = dash2sim_core::geo::Geodetic::new(lat, lon, h).map_err(|e| Error::refused("map origin", e))?;
    let projection = Projection::new(origin)?;
    let network = super::road::road(&view, &projection, 0.0)?;
    let name = map.file_name().map_or_else(|| "map".to_string(), |n| n.to_string_lossy().into_owned());
    let drive = opendrive(&network, &projection, &name)?;
    let partial = out.with_extension("partial");
    std::fs::write(&partial, &drive.xodr).map_err(|e| Error::file(&partial, e))?;
    std::fs::rename(&partial, out).map_err(|e| Error::file(out, e))?;
    Ok(drive)
}
