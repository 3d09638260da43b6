//! Pose-graph files: g2o 3D and TORO 3D, read into a [`GraphFile`] and turned into a
//! [`PoseGraph`], or written back from one.
//!
//! Both formats may be mixed in one file; the format of a file is that of its first
//! recognised line. Unknown tags are skipped with one warning naming them; a file in which
//! nothing is a vertex or an edge is an error. Malformed lines, non-finite numbers,
//! duplicate vertices and edges to missing vertices are errors naming the file and line.
//! An information matrix that is not positive definite (some public files have them, and
//! GTSAM and g2o load them) is replaced by the nearest positive-definite one
//! ([`information::nearest_positive_definite`])
//! with one warning that counts them and names the first lines; [`ReadOptions::strict`]
//! refuses it instead.
//!
//! When a file has edges but no vertices, pose 0 (or the smallest id) starts at the
//! identity and the odometry edges `(i, i+1)` are chained to initialise the others; poses
//! still unreached are reached through any other edge, and whole components that are still
//! unreached start at the identity.

use super::robust::RobustKernel;
use super::{g2o, information, toro, FactorKind, GraphError, PoseGraph, VarKey};
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
    /// Warnings: one for all unknown tags, one for all repaired information matrices.
    pub warnings: Vec<String>,
    /// 1-based lines of the edges whose information matrix was not positive definite and
    /// was replaced by the nearest positive-definite one, in file order.
    pub repaired: Vec<usize>,
}

/// How a file is read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReadOptions {
    /// Refuse information matrices that are not positive definite (an error naming the
    /// line) instead of repairing them.
    pub strict: bool,
    /// Eigenvalue floor of the repair, relative to each matrix's largest eigenvalue.
    pub eigenvalue_floor: f64,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            strict: false,
            eigenvalue_floor: information::REPAIR_EIGENVALUE_FLOOR,
        }
    }
}

/// Where a pose graph built from a file starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitialEstimate {
    /// The file's vertices; chained odometry when it has none.
    #[default]
    File,
    /// Chained odometry from the edges alone (see the module documentation), each
    /// component's first pose at its vertex when the file has one (else the identity);
    /// vertices without edges keep their pose.
    Odometry,
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
    /// Initial estimate of the poses.
    pub initial: InitialEstimate,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            odometry_kernel: RobustKernel::None,
            loop_closure_kernel: RobustKernel::None,
            fix_first: true,
            initial: InitialEstimate::File,
        }
    }
}

/// What is wrong with one line of a pose-graph file (the reader adds the file and line).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LineError {
    /// The line ends before a required field.
    #[error("missing {what} (line ends after {after} fields)")]
    Missing {
        /// The field expected.
        what: String,
        /// Fields read before the end.
        after: usize,
    },
    /// A field that should be a non-negative integer id is not.
    #[error("{what} '{token}' is not a non-negative integer")]
    NotAnId {
        /// The field.
        what: String,
        /// Its text.
        token: String,
    },
    /// A field that should be a number is not.
    #[error("{what} '{token}' is not a number")]
    NotANumber {
        /// The field.
        what: String,
        /// Its text.
        token: String,
    },
    /// A number is NaN or infinite.
    #[error("{what} is {token} (NaN or infinite)")]
    NotFinite {
        /// The field.
        what: String,
        /// Its text.
        token: String,
    },
    /// Fields remain after the last expected one.
    #[error("{tag} has extra field '{token}' after {after} fields")]
    ExtraField {
        /// The line's tag.
        tag: String,
        /// The first extra field.
        token: String,
        /// Fields expected.
        after: usize,
    },
    /// The fields parse but do not make a pose (a zero quaternion, a matrix that is not a
    /// rigid motion).
    #[error("{0}")]
    NotAPose(&'static str),
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

    fn next(&mut self, what: &str) -> Result<&'a str, LineError> {
        let t = self.inner.next().ok_or_else(|| LineError::Missing {
            what: what.to_string(),
            after: self.consumed,
        })?;
        self.consumed += 1;
        Ok(t)
    }

    /// A non-negative integer id.
    pub fn id(&mut self, what: &str) -> Result<u64, LineError> {
        let t = self.next(what)?;
        u64::from_str(t).map_err(|_| LineError::NotAnId {
            what: what.to_string(),
            token: t.to_string(),
        })
    }

    /// A finite number.
    pub fn number(&mut self, what: &str) -> Result<f64, LineError> {
        let t = self.next(what)?;
        let v = f64::from_str(t).map_err(|_| LineError::NotANumber {
            what: what.to_string(),
            token: t.to_string(),
        })?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(LineError::NotFinite {
                what: what.to_string(),
                token: t.to_string(),
            })
        }
    }

    /// Fails if tokens remain.
    pub fn finish(&mut self, tag: &str) -> Result<(), LineError> {
        match self.inner.next() {
            None => Ok(()),
            Some(t) => Err(LineError::ExtraField {
                tag: tag.to_string(),
                token: t.to_string(),
                after: self.consumed,
            }),
        }
    }
}

/// Parses `N` finite numbers.
pub fn parse_fields<const N: usize>(
    tokens: &mut Tokens<'_>,
    tag: &str,
) -> Result<[f64; N], LineError> {
    let mut out = [0.0; N];
    for (k, v) in out.iter_mut().enumerate() {
        *v = tokens.number(&format!("{tag} value {}", k + 1))?;
    }
    Ok(out)
}

impl GraphFile {
    /// Reads a file with the default [`ReadOptions`] (information matrices that are not
    /// positive definite are repaired; see [`GraphFile::repaired`]).
    pub fn read(path: &Path) -> Result<Self, GraphError> {
        Self::read_with(path, &ReadOptions::default())
    }

    /// Reads a file.
    pub fn read_with(path: &Path, options: &ReadOptions) -> Result<Self, GraphError> {
        let text = std::fs::read_to_string(path).map_err(|source| GraphError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_with(&text, path, options)
    }

    /// Parses file content with the default [`ReadOptions`]; `path` is used in messages only.
    pub fn parse(text: &str, path: &Path) -> Result<Self, GraphError> {
        Self::parse_with(text, path, &ReadOptions::default())
    }

    /// Parses file content; `path` is used in messages only.
    ///
    /// Fails on the first malformed line, and when nothing in the file is a vertex or an
    /// edge of either format ([`GraphError::NothingRead`]).
    pub fn parse_with(text: &str, path: &Path, options: &ReadOptions) -> Result<Self, GraphError> {
        let mut parser = Parser::new(path, options);
        for (k, raw) in text.lines().enumerate() {
            let trimmed = raw.trim();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            parser.line(k + 1, trimmed)?;
        }
        parser.finish()
    }

    /// Initial estimates: the vertices, or chained odometry when there are none.
    pub fn initial_estimates(&self) -> Vec<(u64, Isometry3<f64>)> {
        if !self.vertices.is_empty() {
            return self.vertices.iter().map(|v| (v.id, v.pose)).collect();
        }
        chain_initial(&self.edges, &HashMap::new())
    }

    /// Chained odometry from the edges, whatever the vertices say (see
    /// [`InitialEstimate::Odometry`]); in id order.
    pub fn odometry_estimates(&self) -> Vec<(u64, Isometry3<f64>)> {
        let roots: HashMap<u64, Isometry3<f64>> =
            self.vertices.iter().map(|v| (v.id, v.pose)).collect();
        let mut poses: BTreeMap<u64, Isometry3<f64>> =
            chain_initial(&self.edges, &roots).into_iter().collect();
        for v in &self.vertices {
            poses.entry(v.id).or_insert(v.pose);
        }
        poses.into_iter().collect()
    }

    /// Builds a pose graph with the file's estimates and edges.
    pub fn to_pose_graph(&self, options: &BuildOptions) -> Result<PoseGraph, GraphError> {
        let mut graph = PoseGraph::new();
        let initial = match options.initial {
            InitialEstimate::File => self.initial_estimates(),
            InitialEstimate::Odometry => self.odometry_estimates(),
        };
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
            repaired: Vec::new(),
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

/// How many repaired lines a warning names.
const REPAIRED_LINES_NAMED: usize = 3;

/// State of [`GraphFile::parse_with`] between lines.
struct Parser<'a> {
    path: &'a Path,
    options: &'a ReadOptions,
    format: Option<FileFormat>,
    vertices: Vec<FileVertex>,
    edges: Vec<FileEdge>,
    fix_lines: Vec<(u64, usize)>,
    /// Unknown tag → (first line, count).
    unknown: BTreeMap<String, (usize, usize)>,
    /// Vertex id → line.
    seen: HashMap<u64, usize>,
    repaired: Vec<usize>,
}

impl<'a> Parser<'a> {
    fn new(path: &'a Path, options: &'a ReadOptions) -> Self {
        Self {
            path,
            options,
            format: None,
            vertices: Vec::new(),
            edges: Vec::new(),
            fix_lines: Vec::new(),
            unknown: BTreeMap::new(),
            seen: HashMap::new(),
            repaired: Vec::new(),
        }
    }

    fn err(&self, line: usize, message: String) -> GraphError {
        GraphError::Parse {
            path: self.path.to_path_buf(),
            line,
            message,
        }
    }

    /// One non-empty, non-comment line.
    fn line(&mut self, line: usize, trimmed: &str) -> Result<(), GraphError> {
        let (tag, rest) = trimmed
            .split_once(char::is_whitespace)
            .unwrap_or((trimmed, ""));
        let mut tokens = Tokens::new(rest);
        let fmt = match tag {
            "VERTEX3" | "EDGE3" => Some(FileFormat::Toro),
            "VERTEX_SE3:QUAT" | "EDGE_SE3:QUAT" | "FIX" => Some(FileFormat::G2o),
            _ => None,
        };
        if self.format.is_none() {
            self.format = fmt;
        }
        match tag {
            "VERTEX3" | "VERTEX_SE3:QUAT" => self.vertex(tag, &mut tokens, line),
            "EDGE3" | "EDGE_SE3:QUAT" => self.edge(tag, &mut tokens, line),
            "FIX" => {
                for t in rest.split_whitespace() {
                    let id = u64::from_str(t).map_err(|_| {
                        self.err(
                            line,
                            format!("FIX vertex id '{t}' is not a non-negative integer"),
                        )
                    })?;
                    self.fix_lines.push((id, line));
                }
                if rest.trim().is_empty() {
                    return Err(self.err(line, "missing vertex id after FIX".to_string()));
                }
                Ok(())
            }
            other => {
                let e = self.unknown.entry(other.to_string()).or_insert((line, 0));
                e.1 += 1;
                Ok(())
            }
        }
    }

    fn vertex(
        &mut self,
        tag: &str,
        tokens: &mut Tokens<'_>,
        line: usize,
    ) -> Result<(), GraphError> {
        let (id, pose) = if tag == "VERTEX3" {
            toro::parse_vertex(tokens)
        } else {
            g2o::parse_vertex(tokens)
        }
        .map_err(|e| self.err(line, e.to_string()))?;
        if let Some(first) = self.seen.insert(id, line) {
            return Err(self.err(line, format!("vertex {id} already defined on line {first}")));
        }
        self.vertices.push(FileVertex { id, pose, line });
        Ok(())
    }

    fn edge(&mut self, tag: &str, tokens: &mut Tokens<'_>, line: usize) -> Result<(), GraphError> {
        let (from, to, measured, mut information) = if tag == "EDGE3" {
            toro::parse_edge(tokens)
        } else {
            g2o::parse_edge(tokens)
        }
        .map_err(|e| self.err(line, e.to_string()))?;
        if from == to {
            return Err(self.err(line, format!("edge connects vertex {from} with itself")));
        }
        if !information::is_positive_definite(&information) {
            let refuse = |why: String| {
                self.err(
                    line,
                    format!("information matrix is not positive definite{why}"),
                )
            };
            if self.options.strict {
                return Err(refuse(" (--strict)".to_string()));
            }
            information =
                information::nearest_positive_definite(&information, self.options.eigenvalue_floor)
                    .map_err(|e| refuse(format!(": {e}")))?;
            self.repaired.push(line);
        }
        self.edges.push(FileEdge {
            from,
            to,
            measured,
            information,
            line,
        });
        Ok(())
    }

    /// Cross-line checks, warnings and the result.
    fn finish(self) -> Result<GraphFile, GraphError> {
        let unknown = (!self.unknown.is_empty()).then(|| {
            let names: Vec<String> = self
                .unknown
                .iter()
                .map(|(tag, (first, count))| {
                    format!("{tag} ({count} lines, first on line {first})")
                })
                .collect();
            format!("skipped unknown tags: {}", names.join(", "))
        });
        if self.vertices.is_empty() && self.edges.is_empty() {
            return Err(GraphError::NothingRead {
                path: self.path.to_path_buf(),
                detail: unknown.unwrap_or_else(|| "the file has no data lines".to_string()),
            });
        }
        let mut warnings: Vec<String> = unknown
            .map(|u| format!("{}: {u}", self.path.display()))
            .into_iter()
            .collect();
        if !self.repaired.is_empty() {
            warnings.push(self.repair_warning());
        }
        let fixed = self.check_references()?;
        Ok(GraphFile {
            format: self.format.unwrap_or(FileFormat::Toro),
            vertices: self.vertices,
            edges: self.edges,
            fixed,
            warnings,
            repaired: self.repaired,
        })
    }

    fn repair_warning(&self) -> String {
        let named: Vec<String> = self
            .repaired
            .iter()
            .take(REPAIRED_LINES_NAMED)
            .map(|l| format!("{}:{l}", self.path.display()))
            .collect();
        format!(
            "{}: repaired {} information matrices that were not positive definite (nearest \
             positive-definite matrix, eigenvalues floored at {:e} x the largest; --strict \
             refuses them): {}{}",
            self.path.display(),
            self.repaired.len(),
            self.options.eigenvalue_floor,
            named.join(", "),
            if self.repaired.len() > named.len() {
                ", ..."
            } else {
                ""
            }
        )
    }

    /// Edges to missing vertices and `FIX` lines naming unknown ids; returns the fixed ids.
    fn check_references(&self) -> Result<Vec<u64>, GraphError> {
        let no_vertices = self.vertices.is_empty();
        if !no_vertices {
            for e in &self.edges {
                for id in [e.from, e.to] {
                    if !self.seen.contains_key(&id) {
                        return Err(self.err(e.line, format!("edge refers to missing vertex {id}")));
                    }
                }
            }
        }
        let edge_ids: BTreeSet<u64> = if no_vertices {
            self.edges.iter().flat_map(|e| [e.from, e.to]).collect()
        } else {
            BTreeSet::new()
        };
        let mut fixed = Vec::with_capacity(self.fix_lines.len());
        for &(id, line) in &self.fix_lines {
            let known = if no_vertices {
                edge_ids.contains(&id)
            } else {
                self.seen.contains_key(&id)
            };
            if !known {
                return Err(self.err(line, format!("FIX names missing vertex {id}")));
            }
            fixed.push(id);
        }
        Ok(fixed)
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

/// Initial estimates from edges alone: chained odometry, then any edge; a component starts
/// at its smallest id, placed at its pose in `roots` if there, else at the identity.
fn chain_initial(
    edges: &[FileEdge],
    roots: &HashMap<u64, Isometry3<f64>>,
) -> Vec<(u64, Isometry3<f64>)> {
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
        let root = roots
            .get(&start)
            .copied()
            .unwrap_or_else(Isometry3::identity);
        pose.insert(start, root);
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
            (
                "VERTEX3 0 0 0 0 0 0 0\nFIX\n",
                2,
                "missing vertex id",
            ),
            ("VERTEX3 0 0 0 0 0 0 0\nFIX 0 3\n", 2, "missing vertex 3"),
        ];
        let strict = ReadOptions {
            strict: true,
            ..ReadOptions::default()
        };
        for (text, line, needle) in cases {
            match GraphFile::parse_with(text, Path::new("test.g2o"), &strict) {
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

    /// A TORO edge line `i → i+1`, one step along x, with the given TORO-order diagonal.
    fn toro_edge(i: u64, diagonal: [f64; 6]) -> String {
        let mut upper = Vec::new();
        for (a, d) in diagonal.iter().enumerate() {
            upper.push(d.to_string());
            upper.extend(std::iter::repeat_n("0".to_string(), 5 - a));
        }
        format!("EDGE3 {i} {} 1 0 0 0 0 0 {}\n", i + 1, upper.join(" "))
    }

    #[test]
    fn indefinite_information_is_repaired_and_counted() {
        let good = [1.0; 6];
        let text = [
            toro_edge(0, good),
            toro_edge(1, [1.0, 1.0, 1.0, -2.0, 1.0, 1.0]),
            toro_edge(2, good),
            toro_edge(3, [4.0, 0.0, 1.0, 1.0, 1.0, 1.0]),
        ]
        .concat();
        let f = parse(&text).unwrap();
        assert_eq!(f.repaired, vec![2, 4]);
        assert_eq!(f.warnings.len(), 1);
        assert!(
            f.warnings[0].contains("repaired 2 information matrices")
                && f.warnings[0].contains("test.g2o:2, test.g2o:4"),
            "{}",
            f.warnings[0]
        );
        for e in &f.edges {
            assert!(information::is_positive_definite(&e.information));
        }
        // Edge 1's roll (GTSAM index 0) had -2: floored at 1e-9 of the largest (1).
        let floor = information::REPAIR_EIGENVALUE_FLOOR;
        assert!((f.edges[1].information[(0, 0)] - floor).abs() < 1e-15);
        assert_eq!(f.edges[1].information[(1, 1)], 1.0);
        // Edge 3's y (GTSAM index 4) had 0: floored at 1e-9 of the largest (4).
        assert!((f.edges[3].information[(4, 4)] - 4.0 * floor).abs() < 1e-15);
        // Good matrices are untouched, and a repaired graph builds.
        assert_eq!(f.edges[0].information, Matrix6::identity());
        assert!(f.to_pose_graph(&BuildOptions::default()).is_ok());
        // Strict: the first bad line is an error.
        let strict = ReadOptions {
            strict: true,
            ..ReadOptions::default()
        };
        match GraphFile::parse_with(&text, Path::new("test.g2o"), &strict) {
            Err(GraphError::Parse {
                line: 2, message, ..
            }) => {
                assert!(message.contains("--strict"), "{message}")
            }
            other => panic!("{other:?}"),
        }
        // No positive eigenvalue: nothing to floor at, refused even when repairing.
        let hopeless = toro_edge(0, [-1.0; 6]);
        assert!(matches!(
            parse(&hopeless),
            Err(GraphError::Parse { line: 1, .. })
        ));
    }

    #[test]
    fn a_file_with_nothing_readable_is_an_error() {
        for text in ["FOO 1 2\nBAR 3\n", "", "# only a comment\n\n"] {
            match parse(text) {
                Err(e @ GraphError::NothingRead { .. }) => {
                    let msg = e.to_string();
                    assert!(msg.starts_with("test.g2o: no vertex or edge"), "{msg}");
                    if !text.is_empty() && text.starts_with("FOO") {
                        assert!(msg.contains("FOO (1 lines, first on line 1)"), "{msg}");
                    }
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn odometry_estimates_ignore_the_vertices_but_keep_the_root() {
        let text = format!(
            "VERTEX3 0 5 0 0 0 0 0\nVERTEX3 1 9 9 9 0 0 0\nVERTEX3 2 0 0 0 0 0 0\nVERTEX3 7 1 2 3 0 0 0\n{}{}",
            toro_edge(0, [1.0; 6]),
            toro_edge(1, [1.0; 6])
        );
        let f = parse(&text).unwrap();
        let odo = f.odometry_estimates();
        let xs: Vec<(u64, f64)> = odo.iter().map(|(id, p)| (*id, p.translation.x)).collect();
        assert_eq!(xs, vec![(0, 5.0), (1, 6.0), (2, 7.0), (7, 1.0)]);
        let options = BuildOptions {
            initial: InitialEstimate::Odometry,
            ..BuildOptions::default()
        };
        let g = f.to_pose_graph(&options).unwrap();
        assert_eq!(g.pose(1).unwrap().translation.x, 6.0);
        assert!(g.is_fixed(0));
    }
}
