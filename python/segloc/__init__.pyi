"""Type stubs of segloc (the Rust module segloc._segloc, re-exported here)."""

from os import PathLike
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_F64 = npt.NDArray[np.float64]

__version__: str

class SegLocError(Exception):
    """Bad input or a failed call: the message names the file (and line) and the problem."""

class ObjectMap:
    """A map of boulder landmarks in one frame: centroids with covariance, size and provenance."""
    @staticmethod
    def from_points(
        points: npt.ArrayLike,
        sizes: Optional[npt.ArrayLike] = None,
        gravity_aligned: bool = True,
        covariances: Optional[npt.ArrayLike] = None,
        frame: str = "points",
        session: str = "",
    ) -> ObjectMap:
        """A map with one landmark per row of `points` (N, 3), ids 0..N in order."""
    @property
    def points(self) -> _F64:
        """Landmark centroids, (N, 3), metres."""
    @property
    def covariances(self) -> _F64:
        """Position covariances, (N, 3, 3), m^2."""
    @property
    def sizes(self) -> _F64:
        """Boulder diameters, (N,), metres; NaN where unknown."""
    @property
    def ids(self) -> npt.NDArray[np.uint32]:
        """Landmark ids, (N,)."""
    @property
    def observations(self) -> npt.NDArray[np.uint32]:
        """Detections fused into each landmark, (N,)."""
    @property
    def frame(self) -> str:
        """Name of the frame the positions are expressed in."""
    @property
    def session(self) -> str:
        """Session or agent that built the map."""
    @property
    def gravity_aligned(self) -> bool:
        """Whether z is up (gravity known)."""
    @property
    def notes(self) -> dict[str, str]:
        """Free-form provenance."""
    def transformed(self, a_from_b: npt.ArrayLike, frame: str) -> ObjectMap:
        """The same map in another frame: `a_from_b` (4, 4) maps this map's points into `frame`."""
    def __len__(self) -> int: ...

class Detections:
    """Boulder detections of one session, as read from a detections or traverse CSV."""
    @property
    def points(self) -> _F64:
        """Detected centroids, (N, 3), metres."""
    @property
    def rover_positions(self) -> _F64:
        """Rover positions at each detection, (N, 3); NaN rows where unknown."""
    @property
    def sizes(self) -> _F64:
        """Boulder diameters, (N,); NaN where unknown."""
    @property
    def frames(self) -> npt.NDArray[np.uint64]:
        """Camera frame index of each detection, (N,)."""
    @property
    def session(self) -> str:
        """Session or agent id."""
    @property
    def gravity_aligned(self) -> bool:
        """Whether z is up."""
    def __len__(self) -> int: ...

class RelocalizeConfig:
    """The relocalizer's configuration, one section per stage (as `segloc config print`)."""
    def __init__(self, dof: Optional[int] = None, **sections: dict[str, Any]) -> None: ...
    @staticmethod
    def from_toml(text: str) -> RelocalizeConfig:
        """A configuration from TOML text, as written by `segloc config print`."""
    def to_toml(self) -> str:
        """The configuration as TOML text."""
    def to_dict(self) -> dict[str, Any]:
        """The configuration as nested dicts."""
    @property
    def dof(self) -> Optional[int]:
        """The motion model: 4, 6 or None."""

class RelocalizeResult:
    """The answer of one relocalization: the transform with its evidence, or the refusal."""
    @property
    def accepted(self) -> bool:
        """Whether the transform was accepted."""
    @property
    def prior_from_query(self) -> Optional[_F64]:
        """The accepted transform, (4, 4); None when refused."""
    @property
    def best_guess(self) -> Optional[_F64]:
        """The best hypothesis' transform, accepted or not (diagnosis only)."""
    @property
    def information(self) -> _F64:
        """6 x 6 information matrix, (rotation, translation) order, right perturbation."""
    @property
    def inliers(self) -> npt.NDArray[np.uint32]:
        """Inliers, (K, 2): (prior landmark id, query landmark id)."""
    @property
    def rmse_m(self) -> float:
        """RMS residual (m) over the best hypothesis' inliers; NaN without one."""
    @property
    def refusal(self) -> Optional[str]:
        """Why the transform was refused, or None when accepted."""
    @property
    def refusal_code(self) -> Optional[str]:
        """The refusal's stable code (e.g. ``too_few_inliers``), or None when accepted."""
    @property
    def timings_ms(self) -> dict[str, float]:
        """Stage timings, ms."""
    @property
    def dof(self) -> int:
        """Motion model used: 4 or 6."""
    def to_dict(self) -> dict[str, Any]:
        """Everything as nested dicts."""

class Relocalizer:
    """A prior map prepared once; `relocalize(query)` finds `prior_from_query` or refuses."""
    def __init__(self, prior: ObjectMap, config: Optional[RelocalizeConfig] = None) -> None: ...
    def relocalize(self, query: ObjectMap) -> RelocalizeResult:
        """Relocalize `query` against the prior (the GIL is released meanwhile)."""
    @property
    def config(self) -> RelocalizeConfig:
        """The configuration this relocalizer runs with."""

class MergeResult:
    """What a merge produced: the fused map and where each input map was placed."""
    @property
    def merged(self) -> ObjectMap:
        """The merged map in the reference frame."""
    @property
    def reference_from_map(self) -> list[Optional[_F64]]:
        """Per input map, its (4, 4) placement, or None when disconnected."""
    @property
    def merged_flags(self) -> list[bool]:
        """Per input map, whether it joined the reference frame."""
    @property
    def fused(self) -> int:
        """Landmarks fused from two or more maps."""
    def to_dict(self) -> dict[str, Any]:
        """Everything as nested dicts."""

class PoseGraphResult:
    """An optimised pose graph: costs, iterations and the poses."""
    @property
    def initial_cost(self) -> float:
        """Cost at the start."""
    @property
    def final_cost(self) -> float:
        """Cost at the optimum."""
    @property
    def iterations(self) -> int:
        """Solver iterations."""
    @property
    def converged(self) -> bool:
        """Whether a convergence test was met."""
    @property
    def poses(self) -> _F64:
        """Optimised poses, (N, 4, 4), in id order."""
    @property
    def ids(self) -> npt.NDArray[np.uint64]:
        """Pose ids, (N,), ascending."""
    @property
    def warnings(self) -> list[str]:
        """Warnings from reading the file."""
    def to_dict(self) -> dict[str, Any]:
        """The solver's report as nested dicts."""

class Frame:
    """One camera frame of a recorded drive."""
    @property
    def t(self) -> float:
        """Time, s."""
    @property
    def odom_from_rover(self) -> _F64:
        """The odometry's pose of the rover, (4, 4)."""
    @property
    def detections(self) -> _F64:
        """Boulder centroids in the rover frame, (N, 3)."""

class FrameResult:
    """What the localizer returned for one frame."""
    @property
    def frame(self) -> int:
        """Index of the frame."""
    @property
    def prior_from_rover(self) -> Optional[_F64]:
        """The rover's pose in the prior's frame, (4, 4), once known."""
    @property
    def fixes(self) -> list[Tuple[int, int]]:
        """Fixes made during this frame: (anchored frame, inliers)."""
    @property
    def time_ms(self) -> float:
        """Wall time of the call, ms."""

class SessionResult:
    """A finished session: optimised poses, the session's map, the attempts."""
    @property
    def poses(self) -> _F64:
        """Optimised prior_from_rover of every frame, (N, 4, 4)."""
    @property
    def map(self) -> ObjectMap:
        """The session's boulder map."""
    @property
    def first_fix_frame(self) -> Optional[int]:
        """First frame whose pose was known in the prior's frame."""
    @property
    def attempts(self) -> Tuple[int, int]:
        """Relocalization attempts: (accepted, refused)."""

class Localizer:
    """The online localizer of one session: `push_frame` each frame, then `finish`."""
    def __init__(self, prior: Optional[ObjectMap] = None, **config: dict[str, Any]) -> None: ...
    def push_frame(self, frame: Frame) -> FrameResult:
        """Take the next frame; the current pose estimate and the fixes made."""
    def finish(self) -> SessionResult:
        """End the session (final adjustment); no frame is taken after it."""

def read_map(path: _Path) -> ObjectMap:
    """Read a segloc map file."""

def write_map(map: ObjectMap, path: _Path) -> None:
    """Write a segloc map file atomically."""

def read_traverse(path: _Path) -> ObjectMap:
    """Read a LunarLoc traverse CSV fused into landmarks, as `segloc map build` does."""

def read_detections(path: _Path) -> Detections:
    """Read a segloc detections CSV or a LunarLoc traverse CSV."""

def fuse_detections(detections: Detections, **config: Any) -> ObjectMap:
    """Fuse detections into landmarks, one per boulder."""

def merge_maps(
    maps: Sequence[ObjectMap],
    reference: int = 0,
    config: Optional[RelocalizeConfig] = None,
    **merge_config: Any,
) -> MergeResult:
    """Merge maps into the frame of `maps[reference]`."""

def optimize_pose_graph(path: _Path, strict: bool = False, **solver: Any) -> PoseGraphResult:
    """Optimise a g2o or TORO 3D pose-graph file as `segloc graph optimize` does."""

def read_frames(path: _Path) -> list[Frame]:
    """Read a frames file (JSON Lines)."""
