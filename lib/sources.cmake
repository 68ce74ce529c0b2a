# SPDX-License-Identifier: BSD-3-Clause
# The sources of lib/'s libraries, listed once, relative to lib/: lib/CMakeLists.txt builds them
# into sbacameras and sbaformats, and the fuzz targets (fuzz/CMakeLists.txt), which compile them
# in with flags of their own, take the same lists, so that a new file of lib/ reaches every
# build that uses lib/.
set(SBA_LIB_CAMERAS_SOURCES
  cameras/euclidean.cpp
  cameras/colmap_camera.cpp
  cameras/rigid_pose.cpp
  cameras/bal_camera.cpp)
set(SBA_LIB_FORMATS_SOURCES
  formats/bzip2_stream.cpp
  formats/eucsba_io.cpp
  formats/bal_io.cpp
  formats/colmap_io.cpp
  formats/colmap_text.cpp
  formats/colmap_binary.cpp
  formats/colmap_check.cpp
  formats/colmap_sba.cpp
  formats/colmap_problem.cpp
  formats/colmap_covariance.cpp
  formats/colmap_priors.cpp
  formats/colmap_database.cpp
  formats/bundler_io.cpp
  formats/nvm_io.cpp
  formats/output_file.cpp
  formats/ply.cpp)
# The lists as paths from lib_dir, in out_var.
function(sba_lib_sources out_var lib_dir)
  set(paths)
  foreach(source ${SBA_LIB_CAMERAS_SOURCES} ${SBA_LIB_FORMATS_SOURCES})
    list(APPEND paths ${lib_dir}/${source})
  endforeach()
  set(${out_var} ${paths} PARENT_SCOPE)
endfunction()
