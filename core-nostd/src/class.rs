//! The object classes, in one table: the names files and logs write, the codes a
//! `Track3d` record carries (`docs/binlog.md`), and the kind of road user each is for the
//! score. The pipeline's profile, the log's import and export, and `verify` all read it here.

use crate::score::AgentKind;

/// An object class of the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Class {
    /// Lower-case name, as files and logs write it.
    pub name: &'static str,
    /// Its code in `Track3d` records: its index in [`CLASSES`].
    pub code: i64,
    /// What kind of road user it is for the score.
    pub kind: AgentKind,
}

const fn class(name: &'static str, code: i64, kind: AgentKind) -> Class {
    Class { name, code, kind }
}

/// `car`.
pub const CAR: Class = class("car", 0, AgentKind::Vehicle);
/// `truck`.
pub const TRUCK: Class = class("truck", 1, AgentKind::Vehicle);
/// `bus`.
pub const BUS: Class = class("bus", 2, AgentKind::Vehicle);
/// `motorcycle`.
pub const MOTORCYCLE: Class = class("motorcycle", 3, AgentKind::Vehicle);
/// `bicycle`.
pub const BICYCLE: Class = class("bicycle", 4, AgentKind::Vru);
/// `pedestrian`.
pub const PEDESTRIAN: Class = class("pedestrian", 5, AgentKind::Vru);
/// `cone`.
pub const CONE: Class = class("cone", 6, AgentKind::Object);
/// `drum`.
pub const DRUM: Class = class("drum", 7, AgentKind::Object);
/// `barricade`.
pub const BARRICADE: Class = class("barricade", 8, AgentKind::Object);
/// `barrier`.
pub const BARRIER: Class = class("barrier", 9, AgentKind::Object);
/// `arrow_board`.
pub const ARROW_BOARD: Class = class("arrow_board", 10, AgentKind::Object);
/// `sign`.
pub const SIGN: Class = class("sign", 11, AgentKind::Object);

/// The classes, in the order of their codes.
pub const CLASSES: [Class; 12] =
    [CAR, TRUCK, BUS, MOTORCYCLE, BICYCLE, PEDESTRIAN, CONE, DRUM, BARRICADE, BARRIER, ARROW_BOARD, SIGN];

/// The code of a class the table does not have.
pub const OTHER_CODE: i64 = 255;
/// The name of a code the table does not have.
pub const OTHER_NAME: &str = "other";

/// Names other datasets give road users (an objects CSV from elsewhere): read for the score,
/// never written to a log (their code is [`OTHER_CODE`]).
const OTHER_ROAD_USERS: [(&str, AgentKind); 8] = [
    ("van", AgentKind::Vehicle),
    ("trailer", AgentKind::Vehicle),
    ("vehicle", AgentKind::Vehicle),
    ("construction_vehicle", AgentKind::Vehicle),
    ("cyclist", AgentKind::Vru),
    ("person", AgentKind::Vru),
    ("flagger", AgentKind::Vru),
    ("worker", AgentKind::Vru),
];

/// The class of a name, if the table has it.
pub fn by_name(name: &str) -> Option<&'static Class> {
    CLASSES.iter().find(|c| c.name == name)
}

/// The class of a code, if the table has it.
pub fn by_code(code: i64) -> Option<&'static Class> {
    usize::try_from(code).ok().and_then(|i| CLASSES.get(i))
}

/// The code of a class name ([`OTHER_CODE`] for one the table does not have).
pub fn code_of(name: &str) -> i64 {
    by_name(name).map_or(OTHER_CODE, |c| c.code)
}

/// The name of a code ([`OTHER_NAME`] for one the table does not have).
pub fn name_of(code: i64) -> &'static str {
    by_code(code).map_or(OTHER_NAME, |c| c.name)
}

/// The kind of road user a class name is: the table's, or another dataset's name for a
/// vehicle or a vulnerable road user; anything else is an object.
pub fn kind_of(name: &str) -> AgentKind {
    by_name(name)
        .map(|c| c.kind)
        .or_else(|| OTHER_ROAD_USERS.iter().find(|(n, _)| *n == name).map(|(_, k)| *k))
        .unwrap_or(AgentKind::Object)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_code_is_its_index_and_names_and_codes_go_both_ways() {
        for (i, c) in CLASSES.iter().enumerate() {
            assert_eq!(c.code, i as i64, "{}", c.name);
            assert_eq!((code_of(c.name), name_of(c.code)), (c.code, c.name));
        }
        assert_eq!((code_of("tram"), name_of(12), name_of(-1)), (OTHER_CODE, OTHER_NAME, OTHER_NAME));
    }

    #[test]
    fn other_datasets_road_users_are_scored_as_such_and_anything_unknown_is_an_object() {
        assert_eq!(kind_of("truck"), AgentKind::Vehicle);
        assert_eq!(kind_of("bicycle"), AgentKind::Vru);
        assert_eq!(kind_of("worker"), AgentKind::Vru);
        assert_eq!(kind_of("construction_vehicle"), AgentKind::Vehicle);
        assert_eq!(kind_of("drum"), AgentKind::Object);
        assert_eq!(kind_of("tram"), AgentKind::Object);
        assert_eq!(code_of("worker"), OTHER_CODE, "read for the score, never written");
    }
}
