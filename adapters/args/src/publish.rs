//! `PublishRequest` as arguments: `dash2sim scenario publish` and the `camera_sim` example
//! take the same.

use std::ffi::OsString;
use std::path::PathBuf;

use dash2sim_sim::scenario::publish::PublishRequest;

use crate::{Driver, Profile, Receiver};

/// What to publish and how fast ([`PublishRequest`]), as the two binaries take it.
#[derive(Clone, Debug, clap::Args)]
pub struct PublishArgs {
    /// Seed of the generated drive.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// How the ego drives through the work zone.
    #[arg(long, value_enum, default_value = "careful")]
    pub driver: Driver,
    /// Length of the drive, s (1–600).
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// How far the sensors are from ideal: `ideal`, `typical` or `hard` (docs/scenario.md).
    #[arg(long, value_enum, default_value = "typical")]
    pub profile: Profile,
    /// The GNSS receiver: `good` (σ 1–2 m) or `phone` (σ 3–10 m).
    #[arg(long, value_enum, default_value = "good")]
    pub receiver: Receiver,
    /// Frames per second (a multiple of the receiver's 5 Hz).
    #[arg(long, default_value_t = 10)]
    pub fps: u32,
    /// Drive the road this many times (frame numbers and clocks go on; the road starts again).
    #[arg(long, default_value_t = 1)]
    pub laps: u32,
    /// Report at least this many 3D detections a frame (up to 64), adding static cones beside
    /// the road where the drive has fewer: a load test's worst case.
    #[arg(long, default_value_t = 0)]
    pub objects: usize,
    /// Publish this many times faster than real time.
    #[arg(long, default_value_t = 1.0)]
    pub speedup: f64,
    /// Service prefix.
    #[arg(long, default_value = dash2sim_linux::record::bridge::DEFAULT_PREFIX)]
    pub prefix: String,
    /// Also publish a 1920×1080×3 image per frame on the image service.
    #[arg(long)]
    pub images: bool,
    /// Write the GNSS receiver's NMEA here at its rate (a pty, FIFO or file).
    #[arg(long, value_name = "PATH")]
    pub nmea_out: Option<PathBuf>,
    /// Write the wheel-speed CAN frames here as candump lines at their rate (a FIFO or file).
    #[arg(long, value_name = "PATH")]
    pub can_out: Option<PathBuf>,
    /// Also write this many CAN frames a second to --can-out, of a message the logger does
    /// not use (J1939 engine speed), in bursts every 10 ms: a busy vehicle bus.
    #[arg(long, value_name = "HZ", default_value_t = 0)]
    pub bus_load: u32,
    /// Print what was published, per kind, as JSON (else `N frames published`).
    #[arg(long)]
    pub json: bool,
}

impl PublishArgs {
    /// What a run published, as the binaries print it.
    pub fn render(&self, published: &dash2sim_sim::scenario::publish::Published) -> String {
        if self.json {
            serde_json::to_string(published).unwrap_or_default()
        } else {
            format!("{} frames published", published.frames)
        }
    }
}

impl From<&PublishArgs> for PublishRequest {
    fn from(a: &PublishArgs) -> Self {
        PublishRequest {
            seed: a.seed,
            driver: a.driver.into(),
            seconds: a.seconds,
            profile: a.profile.into(),
            receiver: a.receiver.into(),
            fps: a.fps,
            laps: a.laps,
            objects: a.objects,
            speedup: a.speedup,
            prefix: a.prefix.clone(),
            images: a.images,
            nmea_out: a.nmea_out.clone(),
            can_out: a.can_out.clone(),
            bus_load: a.bus_load,
        }
    }
}

/// The arguments of `scenario publish` (after those two words) that publish `request`: what
/// a program starting `dash2sim` as its camera process passes (the demo).
pub fn arguments(request: &PublishRequest) -> Vec<OsString> {
    fn name(value: impl clap::ValueEnum) -> String {
        value.to_possible_value().map(|v| v.get_name().to_owned()).unwrap_or_default()
    }
    let mut args: Vec<OsString> = [
        ("--seed", request.seed.to_string()),
        ("--driver", name(Driver::from(request.driver))),
        ("--seconds", request.seconds.to_string()),
        ("--profile", name(Profile::from(request.profile))),
        ("--receiver", name(Receiver::from(request.receiver))),
        ("--fps", request.fps.to_string()),
        ("--laps", request.laps.to_string()),
        ("--objects", request.objects.to_string()),
        ("--speedup", request.speedup.to_string()),
        ("--prefix", request.prefix.clone()),
        ("--bus-load", request.bus_load.to_string()),
    ]
    .into_iter()
    .flat_map(|(flag, value)| [OsString::from(flag), OsString::from(value)])
    .collect();
    for (flag, path) in [("--nmea-out", &request.nmea_out), ("--can-out", &request.can_out)] {
        if let Some(path) = path {
            args.extend([OsString::from(flag), path.clone().into_os_string()]);
        }
    }
    if request.images {
        args.push("--images".into());
    }
    args
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Publish {
        #[command(flatten)]
        args: PublishArgs,
    }

    #[test]
    fn a_request_s_arguments_parse_back_into_the_same_request() {
        let request = PublishRequest {
            seed: 7,
            driver: dash2sim_sim::scenario::Driver::KnifeEdge,
            seconds: 12.5,
            profile: dash2sim_sim::scenario::profile::Profile::Hard,
            receiver: dash2sim_sim::scenario::profile::Receiver::Phone,
            fps: 20,
            laps: 2,
            objects: 9,
            speedup: 3.0,
            prefix: "dash2sim-test/args".to_owned(),
            images: true,
            nmea_out: Some(PathBuf::from("/tmp/gnss.fifo")),
            can_out: Some(PathBuf::from("/tmp/can.fifo")),
            bus_load: 400,
        };
        let parsed = Publish::try_parse_from(std::iter::once(OsString::from("publish")).chain(arguments(&request)))
            .expect("the arguments parse");
        assert_eq!(PublishRequest::from(&parsed.args), request);
        let default = PublishRequest { images: false, nmea_out: None, can_out: None, ..request };
        let parsed = Publish::try_parse_from(std::iter::once(OsString::from("publish")).chain(arguments(&default)))
            .expect("the arguments parse");
        assert_eq!(PublishRequest::from(&parsed.args), default);
    }
}
