// The Python module's parts, one file each: data sets (bind_data.cc), local maps
// (bind_local_map.cc), graphs (bind_graph.cc), the online loop (bind_online.cc) and the
// jobs (bind_jobs.cc).
#ifndef SUBSLAM_PYTHON_BINDINGS_H_
#define SUBSLAM_PYTHON_BINDINGS_H_

#include <pybind11/pybind11.h>

namespace subslam::python {

void BindData(pybind11::module_& m);
void BindLocalMaps(pybind11::module_& m);
void BindGraphs(pybind11::module_& m);
void BindOnline(pybind11::module_& m);
void BindJobs(pybind11::module_& m);

}  // namespace subslam::python

#endif  // SUBSLAM_PYTHON_BINDINGS_H_
