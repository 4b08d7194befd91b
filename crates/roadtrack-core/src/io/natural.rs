//! Natural ordering of file names: `frame2.png` before `frame10.png`.

use std::cmp::Ordering;

/// Compares two strings treating each run of ASCII digits as one number.
///
/// Equal numbers with different zero padding (`01` vs `1`) fall back to the shorter run first,
/// so the order is total and deterministic.
// Choice: a 30-line function rather than a crate; the candidates (natord) are unmaintained
// and this is the whole of what we need.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let na = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let nb = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (da, db) = (&a[..na], &b[..nb]);
                let ta = trim_zeros(da);
                let tb = trim_zeros(db);
                let ord = ta
                    .len()
                    .cmp(&tb.len())
                    .then_with(|| ta.cmp(tb))
                    .then(na.cmp(&nb));
                if ord != Ordering::Equal {
                    return ord;
                }
                a = &a[na..];
                b = &b[nb..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let n = d.iter().take_while(|&&c| c == b'0').count();
    &d[n..]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_sort_by_value() {
        let mut v = vec!["f10.png", "f2.png", "f1.png", "f002.png", "g1.png", "f.png"];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(
            v,
            ["f.png", "f1.png", "f2.png", "f002.png", "f10.png", "g1.png"]
        );
    }

    #[test]
    fn zero_padded_names_keep_numeric_order() {
        let mut v: Vec<String> = (1..=120).rev().map(|i| format!("{i:06}.jpg")).collect();
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(v[0], "000001.jpg");
        assert_eq!(v[119], "000120.jpg");
    }

    #[test]
    fn long_numbers_do_not_overflow() {
        assert_eq!(
            natural_cmp("a99999999999999999999999", "a100000000000000000000000"),
            Ordering::Less
        );
    }
}
