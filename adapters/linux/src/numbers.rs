//! Numbers written comma-separated (`60.2711,24.8572,20`): the form a request's origin,
//! camera and IMU mounts and bounding box are written in, parsed by one rule — each a finite
//! decimal number, spaces around it allowed.

use crate::{Error, Result};

/// The numbers of `text`; an error saying `expected {form}` when one is not a finite number.
pub(crate) fn comma_separated(text: &str, form: &str) -> Result<Vec<f64>> {
    text.split(',')
        .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| Error::invalid(format!("expected {form}")))
}

#[cfg(test)]
mod tests {
    use super::comma_separated;

    #[test]
    fn every_part_must_be_a_finite_number() {
        assert_eq!(comma_separated(" 1.5, -2,3e2 ", "A,B,C").expect("numbers"), [1.5, -2.0, 300.0]);
        for bad in ["", "1,,2", "1,a", "1,nan", "inf,1", "1;2"] {
            let e = comma_separated(bad, "A,B numbers").expect_err(bad);
            assert_eq!(e.to_string(), "expected A,B numbers", "{bad}");
        }
    }
}
