// The extension module behind `import subslam` (python/subslam/__init__.py wraps it).
#include "bindings.h"
#include "convert.h"
#include "subslam/pipeline/build_info.h"

PYBIND11_MODULE(_subslam, m) {
  m.doc() = "subslam: submap-based landmark SLAM (docs/python.md)";
  m.attr("__version__") = subslam::pipeline::Version();
  subslam::python::RegisterExceptions();
  subslam::python::BindData(m);
  subslam::python::BindLocalMaps(m);
  subslam::python::BindGraphs(m);
  subslam::python::BindOnline(m);
  subslam::python::BindJobs(m);
}
