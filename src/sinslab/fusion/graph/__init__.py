"""A factor-graph estimator beside the Kalman filter: the same INS/GNSS inputs solved by
GTSAM (optional: ``pip install 'sinslab[graph]'``; ``gtsam`` is imported only when a graph
is solved, so the core never needs it).

- :mod:`.frame`: the graph's fixed world frame (the ENU tangent frame at the start) and
  the exact conversions to and from sinslab's WGS-84 navigation state;
- :mod:`.translate`: the filter's IMU noise, bias random walk, initial covariance and fix
  σ translated once into GTSAM's preintegration parameters, priors and noise models;
- :mod:`.build`: keyframes, the IMU cut at them, fix factors (``GPSFactorArm``, a velocity
  factor with the lever arm), priors;
- :mod:`.solve`: the incremental fixed-lag smoother, the batch Levenberg–Marquardt, σ from
  the marginals, the solution at the filter epochs;
- :mod:`.estimator`: :func:`graph_navigate`, the entry point, its result
  :class:`GraphRun`, and :class:`GraphEstimator`, the graph as the estimator of a recorded
  run (``sinslab navigate --estimator graph``, :mod:`sinslab.fusion.estimators`);
- :mod:`.raw`: raw GNSS in the graph — the receiver clock (bias, drift, inter-system biases)
  as a variable of every keyframe, pseudorange and range-rate factors with the tightly
  coupled filter's observation model (:func:`~sinslab.fusion.graph.raw.graph_navigate_raw`).

The physics differ from the filter's in one place, the frame: GTSAM integrates in a fixed
frame with the constant gravity of its origin and a Coriolis term, sinslab in the moving
local level frame with normal gravity at the vehicle (docs/methods/graph.md measures for
which distances and durations that is below the errors compared).
"""
from sinslab.fusion.graph.estimator import GraphEstimator, GraphRun, GraphSpec, graph_navigate
from sinslab.fusion.graph.translate import GraphImuModel, require_gtsam

__all__ = ["GraphRun", "GraphSpec", "GraphEstimator", "graph_navigate", "GraphImuModel", "require_gtsam"]
