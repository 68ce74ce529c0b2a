/* SPDX-License-Identifier: BSD-3-Clause */
// COLMAP sparse models in pysba: lib/'s reader and writer (formats/colmap_io.h), and the
// refinement sbarefine runs on a model (formats/colmap_sba.h). The model crosses into Python
// as plain values (tuples, lists and numpy arrays) that pysba/__init__.py turns into its
// ColmapModel, and comes back as that ColmapModel's attributes, read and checked here.
#ifndef PYSBA_COLMAP_H
#define PYSBA_COLMAP_H

#include <pybind11/pybind11.h>

namespace pysba {

namespace py = pybind11;

// Adds read_colmap, write_colmap and refine_colmap to the module.
void add_colmap(py::module_ &mod);

}  // namespace pysba

#endif  // PYSBA_COLMAP_H
