//! What a highway way means for driving: which ways carry cars, how many lanes each
//! way, how wide, in which direction, how fast — from its tags with the defaults of
//! the OSM wiki, osm2lanes and SUMO's typemap (docs/map-tile.md) where tags are missing or
//! unreadable.

use super::Way;

/// Lane width when no `width` tag says otherwise, metres.
pub const DEFAULT_LANE_WIDTH_M: f64 = 3.5;

/// Highway types motor vehicles drive on.
const DRIVABLE: [&str; 18] = [
    "motorway",
    "motorway_link",
    "trunk",
    "trunk_link",
    "primary",
    "primary_link",
    "secondary",
    "secondary_link",
    "tertiary",
    "tertiary_link",
    "unclassified",
    "residential",
    "service",
    "living_street",
    "road",
    "busway",
    "track",
    "escape",
];

/// The driving interpretation of one highway way.
#[derive(Clone, Debug, PartialEq)]
pub struct RoadSpec {
    /// The `highway` value.
    pub class: String,
    /// Lanes in the way's direction (after `oneway=-1` the way is read backwards).
    pub forward_lanes: u8,
    /// Lanes against it.
    pub backward_lanes: u8,
    /// Width of each lane, metres.
    pub lane_width: f64,
    /// Speed limit, m/s, when tagged and readable.
    pub speed_limit: Option<f64>,
    /// `oneway=-1`: traffic runs against the way's node order.
    pub reversed: bool,
}

impl RoadSpec {
    /// Total lanes.
    pub fn lanes(&self) -> u8 {
        self.forward_lanes.saturating_add(self.backward_lanes)
    }
}

/// A positive whole number of lanes, or why not.
fn lane_count(value: &str) -> Result<u8, String> {
    match value.trim().parse::<u8>() {
        Ok(0) => Err("0 lanes".to_owned()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("{value:?} is not a lane count")),
    }
}

/// A width in metres (`3.5`, `3.5 m`, `12'6"` is not supported), or why not.
fn metres(value: &str) -> Result<f64, String> {
    let v = value.trim().trim_end_matches('m').trim();
    match v.parse::<f64>() {
        Ok(w) if w.is_finite() && w > 0.0 && w < 100.0 => Ok(w),
        _ => Err(format!("{value:?} is not a width in metres")),
    }
}

/// A speed limit in m/s: km/h unless it says `mph`; `none`, `walk`, `signals` and zone
/// codes (`DE:urban`) are not numbers.
fn speed(value: &str) -> Result<f64, String> {
    let v = value.trim();
    let (number, factor) = match v.strip_suffix("mph") {
        Some(n) => (n.trim(), 1609.344 / 3600.0),
        None => (v.trim_end_matches("km/h").trim(), 1.0 / 3.6),
    };
    match number.parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 && s < 400.0 => Ok(s * factor),
        _ => Err(format!("maxspeed {value:?} is not a speed")),
    }
}

/// The driving interpretation of `way`, or `None` when it is not a road for cars; problems
/// with its tags go to `warnings` (the default is used instead).
pub fn interpret(way: &Way, warnings: &mut Vec<String>) -> Option<RoadSpec> {
    let class = way.tag("highway")?;
    if !DRIVABLE.contains(&class) {
        return None;
    }
    let mut warn = |why: String| warnings.push(format!("way {}: {why}; default used", way.id));
    let oneway_tag = way.tag("oneway");
    let implied = class == "motorway" || way.tag("junction") == Some("roundabout");
    let (oneway, reversed) = match oneway_tag {
        Some("yes" | "true" | "1") => (true, false),
        Some("-1" | "reverse") => (true, true),
        Some("no" | "false" | "0") => (false, false),
        Some(other) => {
            warn(format!("oneway={other:?} not understood"));
            (implied, false)
        }
        None => (implied, false),
    };
    let read_lanes = |key: &str, warn: &mut dyn FnMut(String)| {
        way.tag(key).and_then(|v| lane_count(v).map_err(|why| warn(format!("{key}: {why}"))).ok())
    };
    let total = read_lanes("lanes", &mut warn);
    let tagged_forward = read_lanes("lanes:forward", &mut warn);
    let tagged_backward = read_lanes("lanes:backward", &mut warn);
    let (forward_lanes, backward_lanes) = if oneway {
        (total.unwrap_or(1), 0)
    } else {
        match (total, tagged_forward, tagged_backward) {
            (_, Some(f), Some(b)) => (f, b),
            (Some(t), Some(f), None) => (f, t.saturating_sub(f).max(1)),
            (Some(t), None, Some(b)) => (t.saturating_sub(b).max(1), b),
            (Some(1), None, None) => (1, 1), // a narrow two-way road: drivable either way
            (Some(t), None, None) => (t.div_ceil(2), t / 2),
            (None, f, b) => (f.unwrap_or(1), b.unwrap_or(1)),
        }
    };
    let lanes = f64::from(forward_lanes.saturating_add(backward_lanes).max(1));
    let width = ["width:carriageway", "width"]
        .iter()
        .find_map(|key| way.tag(key).map(|v| (key, metres(v))))
        .and_then(|(key, parsed)| parsed.map_err(|why| warn(format!("{key}: {why}"))).ok());
    let lane_width = width.map_or(DEFAULT_LANE_WIDTH_M, |w| w / lanes);
    let speed_limit = way.tag("maxspeed").and_then(|v| speed(v).map_err(&mut warn).ok());
    Some(RoadSpec { class: class.to_owned(), forward_lanes, backward_lanes, lane_width, speed_limit, reversed })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn way(tags: &[(&str, &str)]) -> Way {
        Way { id: 7, refs: vec![1, 2], tags: tags.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect() }
    }

    fn spec(tags: &[(&str, &str)]) -> (Option<RoadSpec>, Vec<String>) {
        let mut warnings = Vec::new();
        (interpret(&way(tags), &mut warnings), warnings)
    }

    #[test]
    fn defaults_and_lane_splits_follow_design() {
        let (s, w) = spec(&[("highway", "residential")]);
        let s = s.expect("road");
        assert_eq!((s.forward_lanes, s.backward_lanes, s.lane_width, s.speed_limit), (1, 1, 3.5, None));
        assert!(w.is_empty());
        // Three lanes two-way: ⌈3/2⌉ forward.
        let s = spec(&[("highway", "primary"), ("lanes", "3")]).0.expect("road");
        assert_eq!((s.forward_lanes, s.backward_lanes), (2, 1));
        let s = spec(&[("highway", "primary"), ("lanes", "4"), ("lanes:forward", "3")]).0.expect("road");
        assert_eq!((s.forward_lanes, s.backward_lanes), (3, 1));
        // Motorways and roundabouts are one-way without saying so.
        let s = spec(&[("highway", "motorway"), ("lanes", "3")]).0.expect("road");
        assert_eq!((s.forward_lanes, s.backward_lanes), (3, 0));
        let s = spec(&[("highway", "primary"), ("junction", "roundabout")]).0.expect("road");
        assert_eq!((s.forward_lanes, s.backward_lanes), (1, 0));
        let s = spec(&[("highway", "secondary"), ("oneway", "-1")]).0.expect("road");
        assert!(s.reversed && s.backward_lanes == 0);
        // Width is shared between the lanes; the carriageway width wins.
        let s = spec(&[("highway", "tertiary"), ("lanes", "2"), ("width", "9"), ("width:carriageway", "7 m")]).0;
        assert_eq!(s.expect("road").lane_width, 3.5);
        // Speeds.
        let kmh = spec(&[("highway", "primary"), ("maxspeed", "50")]).0.expect("road");
        assert!((kmh.speed_limit.expect("limit") - 50.0 / 3.6).abs() < 1e-12);
        let mph = spec(&[("highway", "primary"), ("maxspeed", "30 mph")]).0.expect("road");
        assert!((mph.speed_limit.expect("limit") - 13.4112).abs() < 1e-9);
    }

    #[test]
    fn footways_are_not_roads_and_bad_tags_warn_and_default() {
        assert_eq!(spec(&[("highway", "footway")]).0, None);
        assert_eq!(spec(&[("building", "yes")]).0, None);
        let (s, w) = spec(&[("highway", "residential"), ("lanes", "0"), ("width", "abc"), ("maxspeed", "walk")]);
        let s = s.expect("still a road");
        assert_eq!((s.forward_lanes, s.backward_lanes, s.lane_width, s.speed_limit), (1, 1, 3.5, None));
        assert_eq!(w.len(), 3, "{w:?}");
        assert!(w[0].starts_with("way 7: lanes: 0 lanes"), "{w:?}");
        assert!(w.iter().any(|m| m.contains("\"abc\" is not a width")), "{w:?}");
    }
}
