//! # dash2sim-args
//!
//! The command line's words for the libraries' option values, shared by the two binaries that
//! take them (`dash2sim` and the `camera_sim` example). The libraries know no command line
//! (issue #56): their option enums derive nothing of clap. Each enum here mirrors one of
//! theirs, variant for variant, with the help each value shows in `--help`, converts both
//! ways — so a variant added to a library's enum and not here fails to compile instead of
//! going missing from the command line — and gives a parser of the library's type
//! (`#[arg(value_parser = Profile::parser())]`), so the binaries hold the libraries' types.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod errors;
pub mod publish;

pub use publish::PublishArgs;

/// A `clap::ValueEnum` mirroring a library's enum, and the conversions both ways.
macro_rules! mirror {
    ($(#[$meta:meta])* $name:ident => $lib:ty { $($(#[$vmeta:meta])* $variant:ident),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub enum $name {
            $($(#[$vmeta])* $variant),+
        }

        impl $name {
            /// clap's parser of these values, giving the library's.
            pub fn parser() -> impl clap::builder::TypedValueParser<Value = $lib> {
                clap::builder::TypedValueParser::map(clap::builder::EnumValueParser::<$name>::new(), <$lib>::from)
            }
        }

        const _: () = {
            type Library = $lib;
            impl From<$name> for Library {
                fn from(value: $name) -> Self {
                    match value {
                        $($name::$variant => Library::$variant),+
                    }
                }
            }
            impl From<Library> for $name {
                fn from(value: Library) -> Self {
                    match value {
                        $(Library::$variant => $name::$variant),+
                    }
                }
            }
        };
    };
}

mirror! {
    /// `--format`: [`dash2sim_trajectory::Format`].
    Format => dash2sim_trajectory::Format {
        /// `t x y z qx qy qz qw`
        Tum,
        /// 3×4 pose matrices, one per line, no timestamps.
        Kitti,
        /// Reference: EuRoC ground-truth CSV (ns stamps, w-first quaternion); estimate: TUM.
        Euroc,
    }
}

mirror! {
    /// `--speed-source`: [`dash2sim_linux::record::SpeedMessage`].
    SpeedMessage => dash2sim_linux::record::SpeedMessage {
        /// J1939 CCVS1 wheel-based speed.
        Ccvs1,
        /// OBD-II PID 0x0D responses.
        Obd,
    }
}

mirror! {
    /// `--mode`: [`dash2sim_linux::record::VoFrame`].
    VoFrame => dash2sim_linux::record::VoFrame {
        /// 7-DoF Sim(3).
        Full,
        /// Yaw, scale, translation.
        Gravity,
    }
}

mirror! {
    /// `--relative-motion`: [`dash2sim_core::pipeline::RelativeMotion`].
    RelativeMotion => dash2sim_core::pipeline::RelativeMotion {
        /// The camera's VO poses.
        Vo,
        /// Gyro + wheels dead reckoning.
        ImuWheels,
    }
}

mirror! {
    /// `--align`: [`dash2sim_verify::evaluate::Align`].
    Align => dash2sim_verify::evaluate::Align {
        /// No alignment.
        None,
        /// Rotation and translation (evo `-a`).
        Se3,
        /// Rotation, translation and scale (evo `-as`).
        Sim3,
        /// Scale only (evo `-s`).
        Scale,
    }
}

mirror! {
    /// `--pose-relation`: [`dash2sim_verify::evaluate::Relation`].
    Relation => dash2sim_verify::evaluate::Relation {
        /// Translation part, m.
        Trans,
        /// Full transformation, unit-less.
        Full,
        /// Rotation angle, degrees.
        AngleDeg,
        /// Rotation angle, radians.
        AngleRad,
    }
}

mirror! {
    /// `--anchors`: [`dash2sim_sim::fidelity::drive::Anchors`].
    Anchors => dash2sim_sim::fidelity::drive::Anchors {
        /// Every 50 m of the drive, simulated from the true path under the profile's anchor
        /// model (σ 0.3 m per axis; wrong matches in the typical and hard profiles).
        Street,
        /// None: finishing has GNSS and wheel speed only.
        None,
    }
}

mirror! {
    /// `--profile`: [`dash2sim_sim::scenario::profile::Profile`].
    Profile => dash2sim_sim::scenario::profile::Profile {
        /// The kind simulator of old: exact VO orientation, linear drifts, exact mount, every
        /// reported σ the true one. For reproducing old figures only.
        Ideal,
        /// A consumer dashcam on a good day.
        Typical,
        /// A cheap dashcam on a bad day: frequent VO re-initialisation, GNSS outages, more
        /// multipath and misses.
        Hard,
    }
}

mirror! {
    /// `--receiver`: [`dash2sim_sim::scenario::profile::Receiver`].
    Receiver => dash2sim_sim::scenario::profile::Receiver {
        /// A phone-grade receiver: σ 3–10 m wandering, multipath jumps (the generator's
        /// default GNSS model).
        #[value(help = "A phone-grade receiver: σ 3–10 m wandering, multipath jumps ([`GnssModel::default`])")]
        Phone,
        /// A good receiver: σ 1–2 m (the generator's good GNSS model).
        #[value(help = "A good receiver: σ 1–2 m ([`GnssModel::good`])")]
        Good,
    }
}

mirror! {
    /// `--driver`: [`dash2sim_sim::scenario::Driver`].
    Driver => dash2sim_sim::scenario::Driver {
        /// Changes into the open lane well before the taper (the drives of the Dash2Sim
        /// corpus: "the driver completed each route without any incidents").
        Careful,
        /// Changes lanes only once the taper has begun and clips its drums.
        Careless,
        /// Drifts off the carriageway onto the shoulder before the work zone.
        Shoulder,
        /// Swerves across the divider into the oncoming lane and back.
        Oncoming,
        /// Keeps the careful driver's pace on a road signed 60 km/h.
        Speeding,
        /// Closes on a slower vehicle ahead and brakes only at the last moment, stopping a
        /// metre behind it (time to collision below nuPlan's 0.95 s, without contact).
        Tailgating,
        /// Brakes for the zone at 5.5 m/s² and pulls away at 3.5 m/s².
        Harsh,
        /// Careful, on the edge: passes the closure's drums and cones 0.1–0.3 m clear and
        /// brakes at 3 m/s² (its jerk limited); every metric holds.
        KnifeEdge,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn every_value_converts_to_the_librarys_and_back() {
        for v in Driver::value_variants() {
            assert_eq!(Driver::from(dash2sim_sim::scenario::Driver::from(*v)), *v);
        }
        for v in Relation::value_variants() {
            assert_eq!(Relation::from(dash2sim_verify::evaluate::Relation::from(*v)), *v);
        }
        // The names are clap's kebab-case of the variants, as the library's were.
        let names: Vec<String> = Driver::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value())
            .map(|p| p.get_name().to_owned())
            .collect();
        assert!(names.contains(&"knife-edge".to_owned()), "{names:?}");
    }
}
