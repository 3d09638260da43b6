//! The association-problem exchange format (see `../shared/docs/association.md`).
//!
//! ```text
//! n_prior n_query n_assoc epsilon sigma [dof]
//! x y z            (n_prior lines: prior points)
//! x y z            (n_query lines: query points)
//! i j              (n_assoc lines: 0-based prior index, query index)
//! ```
//! `dof` 6 (default): the distance invariant; 4: gravity-aligned. The ground-truth file
//! `PROBLEM.gt` holds the sorted indices of the true associations on its first line.

use nalgebra::Point3;
use segloc_clipper::{Association, Invariant};
use segloc_maps::MapError;
use std::path::Path;

/// One benchmark problem.
#[derive(Clone, Debug)]
pub struct AssociationProblem {
    /// Prior points.
    pub prior: Vec<Point3<f64>>,
    /// Query points.
    pub query: Vec<Point3<f64>>,
    /// Putative associations.
    pub associations: Vec<Association>,
    /// The invariant the header asks for.
    pub invariant: Invariant,
}

/// The ground truth of a problem.
#[derive(Clone, Debug, Default)]
pub struct ProblemTruth {
    /// Indices (into the association list) of the true associations.
    pub inliers: Vec<usize>,
}

/// Read a problem file.
pub fn read_problem(path: &Path) -> Result<AssociationProblem, MapError> {
    let text = std::fs::read_to_string(path).map_err(|e| MapError::read_io(path, e))?;
    parse_problem(&text, path)
}

/// Parse a problem from text; `path` names it in errors.
pub fn parse_problem(text: &str, path: &Path) -> Result<AssociationProblem, MapError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let (line_no, header) = lines
        .next()
        .ok_or_else(|| MapError::parse(path, "empty file: expected a header line"))?;
    let header = parse_header(header, line_no, path)?;
    let (n_prior, n_query) = (header.n_prior, header.n_query);
    let mut point = |what: &str| {
        let (k, l) = lines
            .next()
            .ok_or_else(|| MapError::parse(path, format!("file ends before all {what} points")))?;
        parse_point(l, what, k, path)
    };
    let prior = (0..n_prior)
        .map(|_| point("prior"))
        .collect::<Result<Vec<_>, _>>()?;
    let query = (0..n_query)
        .map(|_| point("query"))
        .collect::<Result<Vec<_>, _>>()?;
    // n_assoc is the header's word: reserve no more than the text can hold (`i j\n` is 4
    // bytes), so a huge count is a short-file error, not an allocation
    let mut associations = Vec::with_capacity(header.n_assoc.min(text.len() / 4));
    for _ in 0..header.n_assoc {
        let (k, l) = lines
            .next()
            .ok_or_else(|| MapError::parse(path, "file ends before all associations"))?;
        associations.push(parse_association(l, (n_prior, n_query), k, path)?);
    }
    Ok(AssociationProblem {
        prior,
        query,
        associations,
        invariant: header.invariant,
    })
}

/// The header line of a problem file.
struct Header {
    n_prior: usize,
    n_query: usize,
    n_assoc: usize,
    invariant: Invariant,
}

/// Parse the header `n_prior n_query n_assoc epsilon sigma [dof]` (line `line_no`).
fn parse_header(header: &str, line_no: usize, path: &Path) -> Result<Header, MapError> {
    let fields: Vec<&str> = header.split_whitespace().collect();
    if fields.len() < 5 || fields.len() > 6 {
        return Err(MapError::parse_at(
            path,
            line_no,
            format!(
                "header: expected 'n_prior n_query n_assoc epsilon sigma [dof]', got '{header}'"
            ),
        ));
    }
    let count = |k: usize, what: &str| -> Result<usize, MapError> {
        fields[k].parse().map_err(|_| {
            MapError::parse_at(
                path,
                line_no,
                format!("header: {what} '{}' is not a count", fields[k]),
            )
        })
    };
    let real = |k: usize, what: &str| -> Result<f64, MapError> {
        match fields[k].parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
            _ => Err(MapError::parse_at(
                path,
                line_no,
                format!("header: {what} '{}' must be a positive number", fields[k]),
            )),
        }
    };
    let (n_prior, n_query, n_assoc) = (
        count(0, "n_prior")?,
        count(1, "n_query")?,
        count(2, "n_assoc")?,
    );
    let (epsilon, sigma) = (real(3, "epsilon")?, real(4, "sigma")?);
    let invariant = match fields.get(5).copied().unwrap_or("6") {
        "6" => Invariant::Distance { epsilon, sigma },
        "4" => Invariant::GravityAligned {
            epsilon,
            sigma,
            epsilon_z: epsilon,
            sigma_z: sigma,
        },
        other => {
            return Err(MapError::parse_at(
                path,
                line_no,
                format!("header: dof must be 4 or 6, got '{other}'"),
            ))
        }
    };
    Ok(Header {
        n_prior,
        n_query,
        n_assoc,
        invariant,
    })
}

/// Parse a point line `x y z` (line `k`, of the `what` points).
fn parse_point(l: &str, what: &str, k: usize, path: &Path) -> Result<Point3<f64>, MapError> {
    let v: Vec<f64> = l
        .split_whitespace()
        .map(|s| s.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            MapError::parse_at(
                path,
                k,
                format!("{what} point: expected 'x y z', got '{l}'"),
            )
        })?;
    match v.as_slice() {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Point3::new(*x, *y, *z)),
        _ => Err(MapError::parse_at(
            path,
            k,
            format!("{what} point: expected three finite numbers, got '{l}'"),
        )),
    }
}

/// Parse an association line `i j` (line `k`), with `i < n_prior` and `j < n_query`.
fn parse_association(
    l: &str,
    (n_prior, n_query): (usize, usize),
    k: usize,
    path: &Path,
) -> Result<Association, MapError> {
    let mut it = l.split_whitespace().map(|s| s.parse::<u32>());
    match (it.next(), it.next(), it.next()) {
        (Some(Ok(i)), Some(Ok(j)), None) if (i as usize) < n_prior && (j as usize) < n_query => {
            Ok(Association { prior: i, query: j })
        }
        _ => Err(MapError::parse_at(
            path,
            k,
            format!("association: expected 'i j' with i < {n_prior} and j < {n_query}, got '{l}'"),
        )),
    }
}

/// An all-to-all problem in the exchange format. For the gravity-aligned invariant the
/// format has one ε and one σ: the horizontal ones are written.
pub fn problem_to_string(
    prior: &[Point3<f64>],
    query: &[Point3<f64>],
    invariant: &Invariant,
) -> String {
    use std::fmt::Write as _;
    let (epsilon, sigma, dof) = match invariant {
        Invariant::Distance { epsilon, sigma } => (*epsilon, *sigma, 6),
        Invariant::GravityAligned { epsilon, sigma, .. } => (*epsilon, *sigma, 4),
    };
    let mut out = format!(
        "{} {} {} {epsilon} {sigma} {dof}\n",
        prior.len(),
        query.len(),
        prior.len() * query.len()
    );
    for p in prior.iter().chain(query) {
        let _ = writeln!(out, "{:.6} {:.6} {:.6}", p.x, p.y, p.z);
    }
    for i in 0..prior.len() {
        for j in 0..query.len() {
            let _ = writeln!(out, "{i} {j}");
        }
    }
    out
}

/// Read the `.gt` file of a problem (its first line: true association indices).
pub fn read_ground_truth(path: &Path) -> Result<ProblemTruth, MapError> {
    let text = std::fs::read_to_string(path).map_err(|e| MapError::read_io(path, e))?;
    let first = text.lines().next().unwrap_or("");
    let inliers = first
        .split_whitespace()
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|_| MapError::parse_at(path, 1, "expected association indices"))?;
    Ok(ProblemTruth { inliers })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_small_problem() {
        let text = "2 2 2 0.3 0.1 4\n0 0 0\n1 0 0\n0 0 0\n0 1 0\n0 0\n1 1\n";
        let p = parse_problem(text, Path::new("p.txt")).unwrap();
        assert_eq!(p.associations.len(), 2);
        assert!(matches!(p.invariant, Invariant::GravityAligned { .. }));
    }

    /// Fuzz regression (issue 25 §3): a huge association count in the header reserved
    /// that many associations before reading them (8 TB for `1000000000000`: the process
    /// aborted).
    #[test]
    fn fuzz_huge_association_count_is_an_error_not_an_allocation() {
        let text = "1 1 1000000000000 0.3 0.1\n0 0 0\n0 0 0\n0 0\n";
        let err = parse_problem(text, Path::new("p.txt"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("p.txt") && err.contains("ends before all associations"),
            "{err}"
        );
    }

    #[test]
    fn names_the_line_of_a_bad_row() {
        let text = "2 2 1 0.3 0.1\n0 0 0\n1 0 nan\n0 0 0\n0 1 0\n0 0\n";
        let err = parse_problem(text, Path::new("p.txt"))
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("p.txt:3:"), "{err}");
        let text = "2 2 1 0.3 0.1\n0 0 0\n1 0 0\n0 0 0\n0 1 0\n0 5\n";
        let err = parse_problem(text, Path::new("p.txt"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("p.txt:6:"), "{err}");
        assert!(parse_problem("2 2 1 0.3\n", Path::new("p.txt")).is_err());
        assert!(parse_problem("2 2 1 0.3 0.1\n0 0 0\n", Path::new("p.txt")).is_err());
    }
}
