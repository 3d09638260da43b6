//! A g2o or TORO file optimised in one call, with the defaults of
//! `segloc graph optimize FILE`: the chordal start without a robust kernel (the relaxation
//! is not robust to wrong loop closures), else the file's vertices (chained odometry when
//! it has none); the first vertex (or the `FIX` ones) fixed.

use super::file::{BuildOptions, GraphFile, ReadOptions};
use super::{
    GraphError, Initialization, OptimizationReport, PoseGraph, RobustKernel, SolverConfig,
};
use std::path::Path;

/// How a file is optimised.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FileSolveOptions {
    /// Refuse information matrices that are not positive definite instead of repairing
    /// them ([`ReadOptions::strict`]).
    pub strict: bool,
    /// Kernel of the loop closures (edges other than `(i, i+1)`).
    pub loop_closure_kernel: RobustKernel,
    /// The solver's settings; its `initialization` is replaced as the module docs say.
    pub solver: SolverConfig,
}

/// What [`optimize_file`] produced.
#[derive(Clone, Debug)]
pub struct FileSolve {
    /// The file as read (warnings, repaired edges).
    pub file: GraphFile,
    /// The optimised graph.
    pub graph: PoseGraph,
    /// The solver's report.
    pub report: OptimizationReport,
}

/// Read `path` and optimise it (see the module docs).
pub fn optimize_file(path: &Path, options: &FileSolveOptions) -> Result<FileSolve, GraphError> {
    let read = ReadOptions {
        strict: options.strict,
        ..ReadOptions::default()
    };
    let file = GraphFile::read_with(path, &read)?;
    let build = BuildOptions {
        loop_closure_kernel: options.loop_closure_kernel,
        ..BuildOptions::default()
    };
    let mut graph = file.to_pose_graph(&build)?;
    let mut solver = options.solver.clone();
    solver.initialization = match options.loop_closure_kernel {
        RobustKernel::None => Initialization::Chordal,
        _ => Initialization::None,
    };
    let report = graph.optimize(&solver)?;
    Ok(FileSolve {
        file,
        graph,
        report,
    })
}

impl FileSolve {
    /// The optimised poses `(id, world_from_rover)`, in id order.
    pub fn poses(&self) -> Vec<(u64, nalgebra::Isometry3<f64>)> {
        let mut poses: Vec<_> = self
            .graph
            .keys()
            .iter()
            .filter_map(|k| match k {
                super::VarKey::Pose(id) => self.graph.pose(*id).map(|p| (*id, p)),
                _ => None,
            })
            .collect();
        poses.sort_by_key(|(id, _)| *id);
        poses
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optimizes_a_small_file_like_the_cli() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.g2o");
        let text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1.2 0 0 0 0 0 1\n\
                    VERTEX_SE3:QUAT 2 2.1 0.3 0 0 0 0 1\n\
                    EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n\
                    EDGE_SE3:QUAT 1 2 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
        std::fs::write(&path, text).unwrap();
        let solved = optimize_file(&path, &FileSolveOptions::default()).unwrap();
        assert!(solved.report.final_cost < 1e-12 && solved.report.initial_cost > 0.01);
        let poses = solved.poses();
        assert_eq!(poses.iter().map(|p| p.0).collect::<Vec<_>>(), [0, 1, 2]);
        assert!((poses[2].1.translation.vector.x - 2.0).abs() < 1e-9);
        let missing = optimize_file(&dir.path().join("none.g2o"), &FileSolveOptions::default());
        assert!(missing.is_err());
    }
}
