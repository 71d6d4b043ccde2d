//! `dash2sim record` on generated work zones (issue #12): the on-device pipeline fed the
//! forms a device sees — VO poses, the GNSS serial capture, wheel speed as J1939 CAN
//! frames, 3D detections in the camera frame, 2D detections — against the truth and
//! against the offline tools on the same inputs.

use dash2sim_core::binlog::Record;
use dash2sim_tests::recorded::record_drive;

#[test]
fn recorded_work_zones_anchor_as_well_as_the_offline_anchorer_and_track_and_verify() {
    for seed in 1..=3 {
        let o = record_drive(seed, 40.0);
        let verification: Vec<_> = o
            .log
            .records
            .iter()
            .filter_map(|r| if let Record::Verification(v) = r { Some(*v) } else { None })
            .collect();
        let s = &o.recording.stats;
        println!(
            "seed {seed}: ego APE {:.3} m (offline anchorer {:.3} m) over the {} frames both anchored ({} by the pipeline, {} offline); 3D tracks MOTA {:.3} IDF1 {:.3} (anchored frames: {:.3} / {:.3}; seen from the ego: {:.3} / {:.3}; true ego pose: MOTA {:.3} IDF1 {:.3}); {} windows, scores {:?}; {} bytes",
            o.ape.0,
            o.ape.1,
            o.ape.2,
            o.anchored.0,
            o.anchored.1,
            o.judged.tracks.0,
            o.judged.tracks.1,
            o.judged.tracks_anchored.0,
            o.judged.tracks_anchored.1,
            o.judged.tracks_relative.0,
            o.judged.tracks_relative.1,
            o.tracks_truth_pose.0,
            o.tracks_truth_pose.1,
            verification.len(),
            verification.iter().map(|v| v.score_e2 as f64 / 100.0).collect::<Vec<_>>(),
            o.recording.log.len(),
        );
        assert_eq!(o.log.stats.damaged, 0);
        assert_eq!(o.recording.issues.total(), 0, "seed {seed}: clean inputs, no issues: {:?}", o.recording.issues);
        // An NMEA epoch is complete when the next one starts: the pipeline sees each fix one
        // epoch (0.2 s) later than a file of fixes says, and may anchor a few frames later.
        assert!(o.anchored.0 + 5 >= o.anchored.1 && o.anchored.0 > 200, "seed {seed}: anchored {:?}", o.anchored);
        assert!(o.ape.0 <= 1.10 * o.ape.1, "seed {seed}: APE {} vs offline {}", o.ape.0, o.ape.1);
        // Against the truth the tracks carry the anchoring error (reported above). Seen from
        // the ego — each frame's tracks moved from the anchored to the true pose — they are
        // as good as the tracker fed the true pose: placing detections through the anchored
        // pose costs the tracker nothing, and re-anchoring (finishing) gets it all back.
        let (relative, truth) = (o.judged.tracks_relative, o.tracks_truth_pose);
        assert!(
            (relative.0 - truth.0).abs() < 0.04 && (relative.1 - truth.1).abs() < 0.04,
            "seed {seed}: {relative:?} vs {truth:?}"
        );
        assert!(
            o.judged.tracks_anchored.1 > 0.5,
            "seed {seed}: IDF1 on anchored frames {:?}",
            o.judged.tracks_anchored
        );
        // A verification record for every 15 s window of anchored driving (the last one partial).
        let anchored_s = s.anchored_frames as f64 / 10.0;
        assert_eq!(verification.len() as f64, (anchored_s / 15.1).ceil(), "seed {seed}");
        assert_eq!(s.windows as usize, verification.len());
        // The log says where it comes from, UTC and observability as events.
        assert!(o.log.records.iter().any(|r| matches!(r, Record::ClockOffset(c) if c.reason == 0)));
    }
}
