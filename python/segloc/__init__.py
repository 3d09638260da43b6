"""segloc: boulder-based global relocalization for lunar rovers.

Bindings of the segloc Rust library (no logic of their own): object maps of boulder
landmarks, relocalization of a query map against a prior map (the rigid transform
``prior_from_query`` with its 6 x 6 information matrix, or a refusal with its reason),
multi-agent map merging, pose-graph optimisation and the online localizer.

    >>> import segloc
    >>> prior = segloc.read_traverse("traverse_3.csv")
    >>> result = segloc.Relocalizer(prior).relocalize(query)
    >>> result.prior_from_query if result.accepted else result.refusal

Bad input raises ``segloc.SegLocError`` with a message naming the file and line.
"""

from ._segloc import (
    Detections,
    Frame,
    FrameResult,
    Localizer,
    MergeResult,
    ObjectMap,
    PoseGraphResult,
    RelocalizeConfig,
    RelocalizeResult,
    Relocalizer,
    SegLocError,
    SessionResult,
    __version__,
    fuse_detections,
    merge_maps,
    optimize_pose_graph,
    read_detections,
    read_frames,
    read_map,
    read_traverse,
    write_map,
)

__all__ = [
    "Detections",
    "Frame",
    "FrameResult",
    "Localizer",
    "MergeResult",
    "ObjectMap",
    "PoseGraphResult",
    "RelocalizeConfig",
    "RelocalizeResult",
    "Relocalizer",
    "SegLocError",
    "SessionResult",
    "__version__",
    "fuse_detections",
    "merge_maps",
    "optimize_pose_graph",
    "read_detections",
    "read_frames",
    "read_map",
    "read_traverse",
    "write_map",
]
