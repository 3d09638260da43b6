//! A small, tolerant parser for Python-style lists of 3-tuples, as found in the
//! `boulders` column of LunarLoc traverses: `[(x, y, z), (x, y, z)]` or `[]`.
//!
//! ```
//! use segloc_maps::parse_point_list;
//! let mut pts = Vec::new();
//! parse_point_list("[(1.0, 2.0, 3.0), [4, 5, 6],]", &mut pts).unwrap();
//! assert_eq!(pts.len(), 2);
//! assert!(parse_point_list("[(1.0, 2.0)]", &mut pts).is_err());
//! ```

use nalgebra::Point3;

use crate::error::{snippet, LineError};

/// Parse a Python-style list of 3-tuples, `[(x, y, z), (x, y, z)]` or `[]`, appending the
/// points to `out`.
///
/// Spaces anywhere, `[x, y, z]` instead of tuples and trailing commas are accepted;
/// non-finite coordinates are refused. Errors say what was expected and quote the input where it went wrong.
pub fn parse_point_list(text: &str, out: &mut Vec<Point3<f64>>) -> Result<(), LineError> {
    let mut p = Cursor {
        s: text.as_bytes(),
        i: 0,
        text,
    };
    p.ws();
    if !p.eat(b'[') {
        return Err(p.expected("a list starting with '['"));
    }
    p.ws();
    if p.eat(b']') {
        return p.end();
    }
    loop {
        let close = if p.eat(b'(') {
            b')'
        } else if p.eat(b'[') {
            b']'
        } else {
            return Err(p.expected("'(x, y, z)' tuples"));
        };
        let mut xyz = [0.0; 3];
        for (k, v) in xyz.iter_mut().enumerate() {
            p.ws();
            *v = p.number(out.len())?;
            p.ws();
            if k < 2 && !p.eat(b',') {
                return Err(p.expected("'(x, y, z)' tuples"));
            }
        }
        if p.eat(b',') {
            p.ws(); // tolerate a trailing comma inside the tuple
        }
        if !p.eat(close) {
            return Err(p.expected("'(x, y, z)' tuples"));
        }
        out.push(Point3::new(xyz[0], xyz[1], xyz[2]));
        p.ws();
        if p.eat(b',') {
            p.ws();
            if p.eat(b']') {
                return p.end();
            }
        } else if p.eat(b']') {
            return p.end();
        } else {
            return Err(p.expected("',' or ']' after a tuple"));
        }
    }
}

struct Cursor<'a> {
    s: &'a [u8],
    i: usize,
    text: &'a str,
}

impl Cursor<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn rest(&self) -> &str {
        // `i` only ever advances over ASCII bytes, so it is a char boundary
        self.text.get(self.i..).unwrap_or("")
    }

    fn expected(&self, what: &str) -> LineError {
        let rest = self.rest();
        if rest.is_empty() {
            format!("boulders: expected {what}, got the end of the field").into()
        } else {
            format!("boulders: expected {what}, got '{}'", snippet(rest, 40)).into()
        }
    }

    fn number(&mut self, index: usize) -> Result<f64, LineError> {
        let start = self.i;
        while self.i < self.s.len() && !matches!(self.s[self.i], b',' | b')' | b']' | b' ' | b'\t')
        {
            self.i += 1;
        }
        let tok = self.text.get(start..self.i).unwrap_or("");
        let v: f64 = tok.parse().map_err(|_| {
            self.i = start;
            self.expected("'(x, y, z)' tuples of numbers")
        })?;
        if !v.is_finite() {
            return Err(format!(
                "boulders: tuple {} has a non-finite coordinate '{tok}'",
                index + 1
            )
            .into());
        }
        Ok(v)
    }

    fn end(&mut self) -> Result<(), LineError> {
        self.ws();
        if self.i == self.s.len() {
            Ok(())
        } else {
            Err(format!(
                "boulders: unexpected text after the list: '{}'",
                snippet(self.rest(), 40)
            )
            .into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Point3<f64>>, String> {
        let mut out = Vec::new();
        parse_point_list(text, &mut out)
            .map(|()| out)
            .map_err(String::from)
    }

    #[test]
    fn accepts_python_forms() {
        assert_eq!(parse("[]").unwrap(), vec![]);
        assert_eq!(parse("  [ ]  ").unwrap(), vec![]);
        assert_eq!(
            parse("[(1, -2.5, 3e-2)]").unwrap(),
            vec![Point3::new(1.0, -2.5, 0.03)]
        );
        assert_eq!(parse("[(1,2,3,),(4,5,6)]").unwrap().len(), 2);
    }

    #[test]
    fn refuses_bad_forms_quoting_the_input() {
        assert_eq!(
            parse("(1, 2, 3)").unwrap_err(),
            "boulders: expected a list starting with '[', got '(1, 2, 3)'"
        );
        assert_eq!(
            parse("[(1, 2, 3) (4, 5, 6)]").unwrap_err(),
            "boulders: expected ',' or ']' after a tuple, got '(4, 5, 6)]'"
        );
        assert!(parse("[(1, 2, 3]").is_err(), "mismatched brackets");
        assert!(parse("[(1, 2, 3, 4)]").is_err());
        assert_eq!(
            parse("[(1, 2, 3), (4, -inf, 6)]").unwrap_err(),
            "boulders: tuple 2 has a non-finite coordinate '-inf'"
        );
        assert_eq!(
            parse("").unwrap_err(),
            "boulders: expected a list starting with '[', got the end of the field"
        );
    }
}
