// The submap graph as a pose graph of its local maps' marginal blocks, for writing in the
// standard formats (graph_format.h: g2o, iSAM, GTSAM) and solving with their tools.
//
// Poses: the anchors, ids 0 … k, P0 fixed; points: the global landmarks, ids k + 1 …, all
// with the graph's estimates. Each local map's factor becomes its marginal blocks — one
// odometry edge start → end anchor (its end pose, with the inverse of Q's end-pose block
// as information) and one point sighting start anchor → landmark per feature (its
// position in the start frame, with the inverse of its 2 × 2 block). This DROPS the
// cross-correlations inside a local map (pose–feature and feature–feature), so solving
// the pose graph is not the same problem: it over-counts shared information and is
// over-confident.
#ifndef SUBSLAM_POSEGRAPH_SUBMAP_MARGINALS_GRAPH_H_
#define SUBSLAM_POSEGRAPH_SUBMAP_MARGINALS_GRAPH_H_

#include "subslam/core/submap_graph.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::posegraph {

PoseGraph SubmapMarginalsGraph(const SubmapGraph& graph);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_SUBMAP_MARGINALS_GRAPH_H_
