//! Pose-graph files: g2o 3D and TORO 3D, read into a [`GraphFile`] and turned into a
//! [`PoseGraph`], or written back from one.
//!
//! Both formats may be mixed in one file; the format of a file is that of its first
//! recognised line. Unknown tags are skipped with one warning naming them. Malformed lines,
//! non-finite numbers, information matrices that are not positive definite, duplicate
//! vertices and edges to missing vertices are errors naming the file and line.
//!
//! When a file has edges but no vertices, pose 0 (or the smallest id) starts at the
//! identity and the odometry edges `(i, i+1)` are chained to initialise the others; poses
//! still unreached are reached through any other edge, and whole components that are still
//! unreached start at the identity.

use super::robust::RobustKernel;
use super::{g2o, toro, FactorKind, GraphError, PoseGraph, VarKey};
use nalgebra::{Isometry3, Matrix6};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// File format of a pose graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FileFormat {
    /// g2o: `VERTEX_SE3:QUAT`, `EDGE_SE3:QUAT`, `FIX`.
    G2o,
    /// TORO: `VERTEX3`, `EDGE3`.
    Toro,
}

impl FileFormat {
    /// Name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            FileFormat::G2o => "g2o",
            FileFormat::Toro => "TORO",
        }
    }
}

/// A vertex read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct FileVertex {
    /// Pose id.
    pub id: u64,
    /// Pose `world_from_rover`.
    pub pose: Isometry3<f64>,
    /// 1-based line number (0 when not read from a file).
    pub line: usize,
}

/// An edge read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct FileEdge {
    /// Pose the measurement is expressed in.
    pub from: u64,
    /// Pose measured.
    pub to: u64,
    /// Measured `from_T_to`.
    pub measured: Isometry3<f64>,
    /// Information matrix in (rotation, translation) order.
    pub information: Matrix6<f64>,
    /// 1-based line number (0 when not read from a file).
    pub line: usize,
}

/// The content of a g2o or TORO file.
#[derive(Clone, Debug, PartialEq)]
pub struct GraphFile {
    /// Format of the first recognised line (TORO for an empty file).
    pub format: FileFormat,
    /// Vertices in file order.
    pub vertices: Vec<FileVertex>,
    /// Edges in file order.
    pub edges: Vec<FileEdge>,
    /// Ids named by `FIX` lines.
    pub fixed: Vec<u64>,
    /// Warnings (one per distinct unknown tag set).
    pub warnings: Vec<String>,
}

/// How a [`GraphFile`] becomes a [`PoseGraph`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BuildOptions {
    /// Kernel of the odometry edges `(i, i+1)`.
    pub odometry_kernel: RobustKernel,
    /// Kernel of every other edge (loop closures).
    pub loop_closure_kernel: RobustKernel,
    /// Fix the gauge: the `FIX` vertices if any, else the first vertex (pose 0 or the
    /// smallest id when the file has no vertices).
    pub fix_first: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            odometry_kernel: RobustKernel::None,
            loop_closure_kernel: RobustKernel::None,
            fix_first: true,
        }
    }
}

/// Whitespace tokens of one line, with typed accessors that explain failures.
pub struct Tokens<'a> {
    inner: std::str::SplitWhitespace<'a>,
    consumed: usize,
}

impl<'a> Tokens<'a> {
    /// Tokens of `text`.
    pub fn new(text: &'a str) -> Self {
        Self {
            inner: text.split_whitespace(),
            consumed: 0,
        }
    }

    fn next(&mut self, what: &str) -> Result<&'a str, String> {
        let t = self
            .inner
            .next()
            .ok_or_else(|| format!("missing {what} (line ends after {} fields)", self.consumed))?;
        self.consumed += 1;
        Ok(t)
    }

    /// A non-negative integer id.
    pub fn id(&mut self, what: &str) -> Result<u64, String> {
        let t = self.next(what)?;
        u64::from_str(t).map_err(|_| format!("{what} '{t}' is not a non-negative integer"))
    }

    /// A finite number.
    pub fn number(&mut self, what: &str) -> Result<f64, String> {
        let t = self.next(what)?;
        let v = f64::from_str(t).map_err(|_| format!("{what} '{t}' is not a number"))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} is {t} (NaN or infinite)"))
        }
    }

    /// Fails if tokens remain.
    pub fn finish(&mut self, tag: &str) -> Result<(), String> {
        match self.inner.next() {
            None => Ok(()),
            Some(t) => Err(format!(
                "{tag} has extra field '{t}' after {} fields",
                self.consumed
            )),
        }
    }
}

/// Parses `N` finite numbers.
pub fn parse_fields<const N: usize>(
    tokens: &mut Tokens<'_>,
    tag: &str,
) -> Result<[f64; N], String> {
    let mut out = [0.0; N];
    for (k, v) in out.iter_mut().enumerate() {
        *v = tokens.number(&format!("{tag} value {}", k + 1))?;
    }
    Ok(out)
}

impl GraphFile {
    /// Reads a file.
    pub fn read(path: &Path) -> Result<Self, GraphError> {
        let text = std::fs::read_to_string(path).map_err(|source| GraphError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses file content; `path` is used in messages only.
    pub fn parse(text: &str, path: &Path) -> Result<Self, GraphError> {
        let err = |line: usize, message: String| GraphError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut format = None;
        let mut vertices = Vec::new();
        let mut edges = Vec::new();
        let mut fix_lines: Vec<(u64, usize)> = Vec::new();
        let mut unknown: BTreeMap<String, (usize, usize)> = BTreeMap::new();
        let mut seen: HashMap<u64, usize> = HashMap::new();
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let trimmed = raw.trim();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            let (tag, rest) = trimmed
                .split_once(char::is_whitespace)
                .unwrap_or((trimmed, ""));
            let mut tokens = Tokens::new(rest);
            let fmt = match tag {
                "VERTEX3" | "EDGE3" => Some(FileFormat::Toro),
                "VERTEX_SE3:QUAT" | "EDGE_SE3:QUAT" | "FIX" => Some(FileFormat::G2o),
                _ => None,
            };
            if fmt.is_some() && format.is_none() {
                format = fmt;
            }
            match tag {
                "VERTEX3" | "VERTEX_SE3:QUAT" => {
                    let (id, pose) = if tag == "VERTEX3" {
                        toro::parse_vertex(&mut tokens)
                    } else {
                        g2o::parse_vertex(&mut tokens)
                    }
                    .map_err(|m| err(line, m))?;
                    if let Some(first) = seen.insert(id, line) {
                        return Err(err(
                            line,
                            format!("vertex {id} already defined on line {first}"),
                        ));
                    }
                    vertices.push(FileVertex { id, pose, line });
                }
                "EDGE3" | "EDGE_SE3:QUAT" => {
                    let (from, to, measured, information) = if tag == "EDGE3" {
                        toro::parse_edge(&mut tokens)
                    } else {
                        g2o::parse_edge(&mut tokens)
                    }
                    .map_err(|m| err(line, m))?;
                    if from == to {
                        return Err(err(
                            line,
                            format!("edge connects vertex {from} with itself"),
                        ));
                    }
                    match super::factors::check_information(&information) {
                        Ok(()) => {}
                        Err(_) => {
                            return Err(err(
                                line,
                                "information matrix is not positive definite".to_string(),
                            ))
                        }
                    }
                    edges.push(FileEdge {
                        from,
                        to,
                        measured,
                        information,
                        line,
                    });
                }
                "FIX" => {
                    let id = tokens.id("vertex id").map_err(|m| err(line, m))?;
                    fix_lines.push((id, line));
                    for t in rest.split_whitespace().skip(1) {
                        let id = u64::from_str(t).map_err(|_| {
                            err(
                                line,
                                format!("FIX vertex id '{t}' is not a non-negative integer"),
                            )
                        })?;
                        fix_lines.push((id, line));
                    }
                }
                other => {
                    let e = unknown.entry(other.to_string()).or_insert((line, 0));
                    e.1 += 1;
                }
            }
        }
        let mut warnings = Vec::new();
        if !unknown.is_empty() {
            let names: Vec<String> = unknown
                .iter()
                .map(|(tag, (first, count))| {
                    format!("{tag} ({count} lines, first on line {first})")
                })
                .collect();
            warnings.push(format!(
                "{}: skipped unknown tags: {}",
                path.display(),
                names.join(", ")
            ));
        }
        if !vertices.is_empty() {
            for e in &edges {
                for id in [e.from, e.to] {
                    if !seen.contains_key(&id) {
                        return Err(err(e.line, format!("edge refers to missing vertex {id}")));
                    }
                }
            }
        }
        let edge_ids: HashMap<u64, ()> = if vertices.is_empty() {
            edges
                .iter()
                .flat_map(|e| [(e.from, ()), (e.to, ())])
                .collect()
        } else {
            HashMap::new()
        };
        let mut fixed = Vec::with_capacity(fix_lines.len());
        for &(id, line) in &fix_lines {
            let known = if vertices.is_empty() {
                edge_ids.contains_key(&id)
            } else {
                seen.contains_key(&id)
            };
            if !known {
                return Err(err(line, format!("FIX names missing vertex {id}")));
            }
            fixed.push(id);
        }
        Ok(Self {
            format: format.unwrap_or(FileFormat::Toro),
            vertices,
            edges,
            fixed,
            warnings,
        })
    }

    /// Initial estimates: the vertices, or chained odometry when there are none.
    pub fn initial_estimates(&self) -> Vec<(u64, Isometry3<f64>)> {
        if !self.vertices.is_empty() {
            return self.vertices.iter().map(|v| (v.id, v.pose)).collect();
        }
        chain_initial(&self.edges)
    }

    /// Builds a pose graph with the file's estimates and edges.
    pub fn to_pose_graph(&self, options: &BuildOptions) -> Result<PoseGraph, GraphError> {
        let mut graph = PoseGraph::new();
        let initial = self.initial_estimates();
        for (id, pose) in &initial {
            graph.add_pose(*id, *pose)?;
        }
        for e in &self.edges {
            let kernel = if e.to == e.from + 1 {
                options.odometry_kernel
            } else {
                options.loop_closure_kernel
            };
            graph.add_between(e.from, e.to, e.measured, e.information, kernel)?;
        }
        if options.fix_first {
            if !self.fixed.is_empty() {
                for &id in &self.fixed {
                    graph.fix(id)?;
                }
            } else if let Some((id, _)) = initial.first() {
                graph.fix(*id)?;
            }
        }
        Ok(graph)
    }

    /// Collects the poses and between factors of a graph for writing.
    ///
    /// Fails on frame variables, priors and relocalization factors, which neither format
    /// can express.
    pub fn from_pose_graph(graph: &PoseGraph, format: FileFormat) -> Result<Self, GraphError> {
        let mut vertices = Vec::new();
        let mut fixed = Vec::new();
        for key in graph.keys() {
            match *key {
                VarKey::Pose(id) => {
                    let pose = graph.value(*key).ok_or(GraphError::UnknownVariable(*key))?;
                    vertices.push(FileVertex { id, pose, line: 0 });
                    if graph.is_fixed(*key) {
                        fixed.push(id);
                    }
                }
                VarKey::Frame(_) | VarKey::Point(_) => {
                    return Err(GraphError::Unrepresentable {
                        what: key.to_string(),
                        format: format.name(),
                    })
                }
            }
        }
        let mut edges = Vec::new();
        for f in graph.factors() {
            match f.kind() {
                FactorKind::Between {
                    from: VarKey::Pose(from),
                    to: VarKey::Pose(to),
                } => edges.push(FileEdge {
                    from,
                    to,
                    measured: *f.measured(),
                    information: *f.information(),
                    line: 0,
                }),
                kind => {
                    return Err(GraphError::Unrepresentable {
                        what: super::factors::describe(&kind),
                        format: format.name(),
                    })
                }
            }
        }
        Ok(Self {
            format,
            vertices,
            edges,
            fixed,
            warnings: Vec::new(),
        })
    }

    /// The file content in `format`.
    pub fn to_text(&self, format: FileFormat) -> String {
        let mut out = String::new();
        for v in &self.vertices {
            let line = match format {
                FileFormat::G2o => g2o::format_vertex(v.id, &v.pose),
                FileFormat::Toro => toro::format_vertex(v.id, &v.pose),
            };
            out.push_str(&line);
            out.push('\n');
        }
        if format == FileFormat::G2o {
            for id in &self.fixed {
                out.push_str(&format!("FIX {id}\n"));
            }
        }
        for e in &self.edges {
            let line = match format {
                FileFormat::G2o => g2o::format_edge(e.from, e.to, &e.measured, &e.information),
                FileFormat::Toro => toro::format_edge(e.from, e.to, &e.measured, &e.information),
            };
            out.push_str(&line);
            out.push('\n');
        }
        out
    }

    /// Writes the file atomically (temporary file in the same directory, then rename).
    pub fn write(&self, path: &Path, format: FileFormat) -> Result<(), GraphError> {
        write_atomic(path, self.to_text(format).as_bytes())
    }
}

/// Writes `bytes` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), GraphError> {
    let io = |source| GraphError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "graph".into());
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

/// Initial estimates from edges alone: chained odometry, then any edge, then identity.
fn chain_initial(edges: &[FileEdge]) -> Vec<(u64, Isometry3<f64>)> {
    let ids: BTreeSet<u64> = edges.iter().flat_map(|e| [e.from, e.to]).collect();
    let mut pose: HashMap<u64, Isometry3<f64>> = HashMap::with_capacity(ids.len());
    let mut odometry: HashMap<u64, Isometry3<f64>> = HashMap::new();
    let mut adjacency: HashMap<u64, Vec<(u64, Isometry3<f64>)>> = HashMap::new();
    for e in edges {
        if e.to == e.from + 1 {
            odometry.entry(e.from).or_insert(e.measured);
        }
        adjacency
            .entry(e.from)
            .or_default()
            .push((e.to, e.measured));
        adjacency
            .entry(e.to)
            .or_default()
            .push((e.from, e.measured.inverse()));
    }
    for &start in &ids {
        if pose.contains_key(&start) {
            continue;
        }
        // A new component: start at the identity, chain odometry forward, then spread.
        pose.insert(start, Isometry3::identity());
        let mut queue = VecDeque::new();
        let mut id = start;
        queue.push_back(id);
        while let Some(z) = odometry.get(&id) {
            let next = id + 1;
            if pose.contains_key(&next) {
                break;
            }
            let p = pose[&id] * z;
            pose.insert(next, p);
            queue.push_back(next);
            id = next;
        }
        while let Some(id) = queue.pop_front() {
            let base = pose[&id];
            if let Some(neighbours) = adjacency.get(&id) {
                for (other, z) in neighbours {
                    if !pose.contains_key(other) {
                        pose.insert(*other, base * z);
                        queue.push_back(*other);
                    }
                }
            }
        }
    }
    ids.into_iter().map(|id| (id, pose[&id])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<GraphFile, GraphError> {
        GraphFile::parse(text, Path::new("test.g2o"))
    }

    #[test]
    fn chained_initial_estimate_follows_odometry() {
        let text = "EDGE3 0 1 1 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n\
                    EDGE3 1 2 1 0 0 0 0 1.5707963267948966 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n\
                    EDGE3 2 3 1 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
        let f = parse(text).unwrap();
        let init = f.initial_estimates();
        assert_eq!(init.len(), 4);
        let p3 = init[3].1.translation.vector;
        assert!((p3 - nalgebra::Vector3::new(2.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn unknown_tags_give_one_warning() {
        let text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nFOO 1 2\nBAR\nFOO 3\n";
        let f = parse(text).unwrap();
        assert_eq!(f.warnings.len(), 1);
        assert!(f.warnings[0].contains("FOO (2 lines, first on line 2)"));
        assert!(f.warnings[0].contains("BAR"));
    }

    #[test]
    fn errors_name_the_line() {
        let cases = [
            ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 0 x 0 0 0 1\n", 2, "not a number"),
            ("VERTEX3 0 0 0 0 0 0\n", 1, "missing"),
            ("VERTEX3 0 0 0 0 0 0 NaN\n", 1, "NaN"),
            ("VERTEX3 0 0 0 0 0 0 0 7\n", 1, "extra field"),
            ("VERTEX3 0 0 0 0 0 0 0\nVERTEX3 0 0 0 0 0 0 0\n", 2, "already defined"),
            (
                "VERTEX3 0 0 0 0 0 0 0\nEDGE3 0 5 1 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n",
                2,
                "missing vertex 5",
            ),
            (
                "EDGE3 0 1 1 0 0 0 0 0 1 0 0 0 0 0 1 0 0 0 0 -1 0 0 0 1 0 0 1 0 1\n",
                1,
                "positive definite",
            ),
        ];
        for (text, line, needle) in cases {
            match parse(text) {
                Err(GraphError::Parse {
                    line: l, message, ..
                }) => {
                    assert_eq!(l, line, "{text}");
                    assert!(message.contains(needle), "{message} lacks {needle}");
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn g2o_round_trip_keeps_everything() {
        let text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n\
                    VERTEX_SE3:QUAT 1 1 2 3 0.1 0.2 0.3 0.927\n\
                    FIX 0\n\
                    EDGE_SE3:QUAT 0 1 1 2 3 0 0 0 1 10 1 0 0 0 0 10 0 0 0 0 10 0 0 0 40 0 0 40 0 40\n";
        let f = parse(text).unwrap();
        let g = f.to_pose_graph(&BuildOptions::default()).unwrap();
        assert!(g.is_fixed(0));
        let back = GraphFile::from_pose_graph(&g, FileFormat::G2o).unwrap();
        let f2 = parse(&back.to_text(FileFormat::G2o)).unwrap();
        assert_eq!(f2.fixed, vec![0]);
        assert_eq!(f2.edges[0].information, f.edges[0].information);
        assert!(
            (f2.vertices[1].pose.to_homogeneous() - f.vertices[1].pose.to_homogeneous())
                .abs()
                .max()
                < 1e-15
        );
    }
}
