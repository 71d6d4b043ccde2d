//! The libraries' errors in the command line's words: a request field the library names
//! ([`dash2sim_linux::Field`]) is shown as the flag that sets it, so a message says what to
//! change on the command line while the library's own messages stay free of it.

use dash2sim_linux::{Error, Field};

/// How the command line sets a request field: the flag a message leads with, and the
/// flags to choose from that it ends with (either, or both).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Words {
    /// The one flag that sets the field.
    pub flag: Option<&'static str>,
    /// The ways to give it, when there are several (or a flag beside the field's own).
    pub ways: Option<&'static str>,
}

impl Words {
    /// One flag.
    const fn flag(flag: &'static str) -> Words {
        Words { flag: Some(flag), ways: None }
    }

    /// Several ways to choose from.
    const fn choice(ways: &'static str) -> Words {
        Words { flag: None, ways: Some(ways) }
    }
}

/// The flag (or the flags) that set `field`, as both binaries spell them.
pub fn words(field: Field) -> Words {
    match field {
        Field::Uere => Words::flag("--uere"),
        Field::Origin => Words {
            flag: Some("--origin"),
            ways: Some("--origin LAT,LON[,H], --map, or GNSS: --nmea or --serial, or --can, --can-iface or --can-replay with --gnss-signals"),
        },
        Field::Map => Words::flag("--map"),
        Field::Dbc => Words::flag("--dbc"),
        Field::SpeedSignal => Words::flag("--speed-signal"),
        Field::GnssSignals => Words::flag("--gnss-signals"),
        Field::Sources => Words::choice("--vo, --nmea, --can, --detections, --detections2d, --imu or --replay; live: --camera, --serial, --can-iface or --can-replay"),
        Field::ImportSources => Words::choice("--nmea, --can, --traj or --objects"),
        Field::Detections2d => Words::flag("--detections2d"),
        Field::SaveInputs => Words::flag("--save-inputs"),
        Field::SegmentMinutes => Words::flag("--segment-minutes"),
        Field::Seconds => Words::flag("--seconds"),
        Field::CanInterface => Words { flag: Some("--can-iface"), ways: Some("--can-replay FILE replays a capture") },
        Field::Cell => Words::flag("--cell"),
        Field::Passes => Words::flag("--passes"),
        Field::Sigma => Words::flag("--sigma"),
        Field::Forget => Words::flag("--forget"),
        Field::Keyframe => Words::flag("--keyframe"),
        Field::Formats => Words::choice("--mcap, --tum, --geojson, --parquet, --nuplan, --commonroad, --scenarionet and/or --openscenario"),
        Field::Mcap => Words::flag("--mcap"),
        Field::Parquet => Words::flag("--parquet"),
        Field::Nuplan => Words::flag("--nuplan"),
        Field::ScenarioSeconds => Words::flag("--scenario-seconds"),
        Field::Duration => Words::flag("--duration"),
        Field::Jobs => Words::flag("--jobs"),
        Field::Speedup => Words::flag("--speedup"),
        Field::Fps => Words::flag("--fps"),
        Field::Laps => Words::flag("--laps"),
    }
}

/// `error` as the command line shows it: a request field's error leads with the flag that
/// sets it, anything else is the library's message as it is.
pub fn message(error: &Error) -> String {
    let (field, message) = match error {
        Error::Request { field, message } => (*field, message.clone()),
        Error::FeatureMissing { field, .. } => (*field, error.to_string()),
        other => return other.to_string(),
    };
    let Words { flag, ways } = words(field);
    let message = match flag {
        Some(flag) => format!("{flag}: {message}"),
        None => message,
    };
    match ways {
        Some(ways) => format!("{message} ({ways})"),
        None => message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_field_is_shown_as_its_flag_and_other_errors_as_they_are() {
        let e = Error::request(Field::Map, "the nuPlan export needs one (a tile or an OpenStreetMap file)");
        assert_eq!(e.to_string(), "the map: the nuPlan export needs one (a tile or an OpenStreetMap file)");
        assert_eq!(message(&e), "--map: the nuPlan export needs one (a tile or an OpenStreetMap file)");
        let e = Error::FeatureMissing {
            field: Field::Parquet,
            krate: "dash2sim-export",
            part: "Parquet export",
            feature: "parquet",
        };
        assert_eq!(
            message(&e),
            "--parquet: this build of dash2sim-export has no Parquet export (its `parquet` feature)"
        );
        let e = Error::FeatureMissing {
            field: Field::Mcap,
            krate: "dash2sim-export",
            part: "MCAP export",
            feature: "mcap",
        };
        assert_eq!(message(&e), "--mcap: this build of dash2sim-export has no MCAP export (its `mcap` feature)");
        let e = Error::request(Field::ImportSources, "nothing to import");
        assert_eq!(message(&e), "nothing to import (--nmea, --can, --traj or --objects)");
        let e = Error::request(Field::CanInterface, "vcan0: No such device");
        assert_eq!(message(&e), "--can-iface: vcan0: No such device (--can-replay FILE replays a capture)");
        let e = Error::invalid("a.csv: no rows");
        assert_eq!(message(&e), "a.csv: no rows");
    }
}
