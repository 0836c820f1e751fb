//! Run identifiers: `YYYYMMDDTHHMMSSZ-hhhhhhhh`, the UTC time a run started (to the
//! second) and the first 8 of the 16 hex digits of the FNV-1a hash ([`crate::hash`]) of
//! its input definition. The time tells runs of one definition apart and sorts them; the
//! hash tells which runs computed the same thing. `summary.json` carries it as `run_id`,
//! and the files beside it belong to that run.

use crate::hash::Fnv1a;
use std::time::{SystemTime, UNIX_EPOCH};

/// The identifier of a run of `definition` (its input as text) started at `start`.
///
/// ```
/// use std::time::{Duration, UNIX_EPOCH};
/// let start = UNIX_EPOCH + Duration::from_secs(1_700_000_000);
/// assert_eq!(fdem_core::run_id::run_id(b"", start), "20231114T221320Z-cbf29ce4");
/// ```
pub fn run_id(definition: &[u8], start: SystemTime) -> String {
    let seconds = match start.duration_since(UNIX_EPOCH) {
        Ok(after) => i64::try_from(after.as_secs()).unwrap_or(i64::MAX),
        Err(before) => -i64::try_from(before.duration().as_secs()).unwrap_or(i64::MAX),
    };
    format!("{}-{:08x}", utc_stamp(seconds), Fnv1a::of(definition) >> 32)
}

/// The UTC time `seconds` after 1970-01-01T00:00:00Z as `YYYYMMDDTHHMMSSZ` (ISO 8601,
/// basic format; a year beyond 9999 or before 0 gets its digits and sign).
pub fn utc_stamp(seconds: i64) -> String {
    let (days, second_of_day) = (seconds.div_euclid(86_400), seconds.rem_euclid(86_400));
    let (year, month, day) = civil_from_days(days);
    let (h, m, s) = (
        second_of_day / 3600,
        second_of_day / 60 % 60,
        second_of_day % 60,
    );
    format!("{year:04}{month:02}{day:02}T{h:02}{m:02}{s:02}Z")
}

/// The proleptic Gregorian date `(year, month 1-12, day 1-31)` of the day `days` after
/// 1970-01-01 (negative before it): H. Hinnant's `civil_from_days`, exact over the whole
/// range of `i64` days divided by a year's.
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    // Days since 0000-03-01, in eras of 400 years (146097 days) that start in March, so
    // that the leap day ends a year.
    let z = days.saturating_add(719_468);
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // [0, 365]
    let mp = (5 * doy + 2) / 153; // [0, 11], March first
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32; // [1, 31]
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32; // [1, 12]
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn leap(y: i64) -> bool {
        (y % 4 == 0 && y % 100 != 0) || y % 400 == 0
    }

    fn month_days(y: i64, m: u32) -> u32 {
        match m {
            2 if leap(y) => 29,
            2 => 28,
            4 | 6 | 9 | 11 => 30,
            _ => 31,
        }
    }

    /// The inverse, by counting: days from 1970-01-01 to `(y, m, d)`.
    fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
        let mut days = 0i64;
        for year in y.min(1970)..y.max(1970) {
            let n = if leap(year) { 366 } else { 365 };
            days += if y >= 1970 { n } else { -n };
        }
        days + (1..m).map(|m| i64::from(month_days(y, m))).sum::<i64>() + i64::from(d) - 1
    }

    #[test]
    fn known_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        assert_eq!(civil_from_days(59), (1970, 3, 1));
        assert_eq!(civil_from_days(10_957), (2000, 1, 1));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        assert_eq!(civil_from_days(19_782), (2024, 2, 29));
        assert_eq!(civil_from_days(-719_468), (0, 3, 1));
        assert_eq!(civil_from_days(2_932_896), (9999, 12, 31));
        assert_eq!(utc_stamp(0), "19700101T000000Z");
        assert_eq!(utc_stamp(951_782_400), "20000229T000000Z");
        assert_eq!(utc_stamp(1_700_000_000), "20231114T221320Z");
        assert_eq!(utc_stamp(-1), "19691231T235959Z");
        assert_eq!(utc_stamp(4_102_444_799), "20991231T235959Z");
    }

    /// Every day from 1600 to 2400 (the leap rules of 1700, 1800, 1900 and 2000 among
    /// them) round-trips through a plain count of days.
    #[test]
    fn every_day_of_eight_centuries_round_trips() {
        let (first, last) = (days_from_civil(1600, 1, 1), days_from_civil(2400, 12, 31));
        let mut expected = (1600, 1, 1);
        for days in first..=last {
            let date = civil_from_days(days);
            assert_eq!(date, expected, "day {days}");
            let (y, m, d) = date;
            assert_eq!(days_from_civil(y, m, d), days);
            // The next day by the calendar.
            expected = if d < month_days(y, m) {
                (y, m, d + 1)
            } else if m < 12 {
                (y, m + 1, 1)
            } else {
                (y + 1, 1, 1)
            };
        }
    }

    #[test]
    fn the_identifier_is_the_start_and_the_definition_s_hash() {
        let start = UNIX_EPOCH + Duration::from_secs(1_700_000_000);
        let id = run_id(b"[simulation]\nduration = 1.0\n", start);
        assert_eq!(id.len(), 25);
        assert!(id.starts_with("20231114T221320Z-"), "{id}");
        let hash = Fnv1a::of(b"[simulation]\nduration = 1.0\n");
        assert_eq!(&id[17..], format!("{:016x}", hash).get(..8).unwrap());
        assert_ne!(run_id(b"other", start), id);
        let later = start + Duration::from_secs(1);
        assert!(run_id(b"[simulation]\nduration = 1.0\n", later) > id);
        let before = UNIX_EPOCH - Duration::from_secs(1);
        assert!(run_id(b"", before).starts_with("19691231T235959Z-"));
    }
}
