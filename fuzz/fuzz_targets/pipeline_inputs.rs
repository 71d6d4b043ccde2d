//! Arbitrary input streams into the on-device pipeline: the bytes are read as the core's
//! replay format (serial bytes, CAN frames, VO poses, 3D and 2D detections with any times
//! in any order) and fed one by one; CAN ids 2 and 3 are a DBC-defined GNSS module (CSS's
//! CANmod.gps) besides NMEA 2000, J1939 and OBD-II. The pipeline never panics, and the log it writes
//! always decodes without damage.
#![no_main]

use dash2sim_core::binlog::{Decoder, Event};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::pipeline::replay::{feed, Reader, MAGIC};
use dash2sim_core::pipeline::{ClassMeta, GnssSignals, Pipeline, PipelineConfig, SpeedSource, Trackers};
use dash2sim_core::score::AgentKind;
use dash2sim_core::track2d::TrackerConfig;
use dash2sim_core::track3d::{Association, ClassConfig, Config3d};
use libfuzzer_sys::fuzz_target;

const CLASS: ClassConfig = ClassConfig {
    association: Association::Distance(2.0),
    min_size: [0.1; 3],
    max_size: [10.0; 3],
    max_ground_offset: 1.0,
    process_noise: [0.01; 10],
    measurement_noise: [0.1; 7],
    initial_velocity_variance: 1.0,
};
const META: [ClassMeta; 2] =
    [ClassMeta { code: 6, kind: AgentKind::Object }, ClassMeta { code: 0, kind: AgentKind::Vehicle }];

fuzz_target!(|data: &[u8]| {
    let mut stream = MAGIC.to_vec();
    stream.extend_from_slice(data);
    let Ok(mut reader) = Reader::new(&stream) else { return };
    let classes = [CLASS, CLASS];
    let Ok(origin) = Geodetic::new(60.0, 25.0, 0.0) else { return };
    let tracker = Config3d { classes: &classes, min_hits: 1, max_age: 2, ground_z: 0.0, static_speed: 0.3 };
    let config = PipelineConfig {
        speed: Some(SpeedSource::Ccvs1),
        gnss_signals: GnssSignals::canmod_gps(),
        ..PipelineConfig::new(origin, &META)
    };
    let mut trackers: Box<Trackers<'_, 8, 4>> = Box::new(Trackers::new(tracker, TrackerConfig::default()));
    let mut pipeline: Box<Pipeline<'_, Vec<u8>, 8, 4, 4096>> =
        Box::new(Pipeline::new(Vec::new(), config, &mut trackers));
    while let Some(Ok((t, input))) = reader.next_input() {
        feed(&mut pipeline, t, &input).expect("a Vec never fails");
    }
    let (log, _, _) = pipeline.finish().expect("a Vec never fails");
    let mut decoder: Box<Decoder> = Box::default();
    let mut damaged = 0;
    let mut on = |e: Event| {
        if matches!(e, Event::Damaged { .. } | Event::NotALog(_) | Event::Lost(_)) {
            damaged += 1;
        }
    };
    decoder.push(&log, &mut on);
    decoder.finish(&mut on);
    assert_eq!(damaged, 0, "the pipeline's log always decodes");
});
