# The libraries libsba calls into, found on the machine at hand and named by two imported
# targets: sba::LAPACK (LAPACK and BLAS) and sba::SuiteSparse (CHOLMOD, AMD, LDL). The build
# includes this file, and so does the installed package (sbaConfig.cmake): a program that links
# the static library then finds these libraries where its own machine keeps them, instead of
# inheriting the build machine's paths.
#
# In:  SBA_PREFER_OPENBLAS  try OpenBLAS first (unless BLA_VENDOR is set)
# Out: LAPACK_LIBRARIES, SUITESPARSE_INCLUDE_DIR, SBA_SUITESPARSE_LIBRARIES, and
#      SBA_DEPENDENCIES_MISSING: empty when everything was found, else what is missing (the
#      caller decides whether that is fatal).

set(SBA_DEPENDENCIES_MISSING "")

# ---- BLAS/LAPACK: OpenBLAS when present, the reference libraries otherwise ----
if(NOT LAPACK_FOUND)
  if(SBA_PREFER_OPENBLAS AND NOT BLA_VENDOR)
    set(BLA_VENDOR OpenBLAS)
    find_package(LAPACK QUIET)
    unset(BLA_VENDOR)
  endif()
  if(NOT LAPACK_FOUND)
    find_package(LAPACK QUIET)
  endif()
endif()
if(NOT LAPACK_FOUND)
  string(APPEND SBA_DEPENDENCIES_MISSING " LAPACK (Debian: liblapack-dev or libopenblas-dev)")
elseif(NOT TARGET sba::LAPACK)
  add_library(sba::LAPACK INTERFACE IMPORTED)
  set_target_properties(sba::LAPACK PROPERTIES INTERFACE_LINK_LIBRARIES "${LAPACK_LIBRARIES}")
endif()

# ---- SuiteSparse (AMD, LDL, CHOLMOD); Debian's libsuitesparse-dev has no CMake package ----
find_path(SUITESPARSE_INCLUDE_DIR suitesparse/cholmod.h)
set(SBA_SUITESPARSE_LIBRARIES "")
foreach(lib cholmod amd ldl suitesparseconfig)
  find_library(SBA_${lib}_LIBRARY ${lib})
  if(SBA_${lib}_LIBRARY)
    list(APPEND SBA_SUITESPARSE_LIBRARIES ${SBA_${lib}_LIBRARY})
  else()
    string(APPEND SBA_DEPENDENCIES_MISSING " ${lib}")
  endif()
endforeach()
if(NOT SUITESPARSE_INCLUDE_DIR)
  string(APPEND SBA_DEPENDENCIES_MISSING " suitesparse/cholmod.h")
endif()
if(SBA_DEPENDENCIES_MISSING MATCHES "cholmod|amd|ldl|suitesparse")
  string(APPEND SBA_DEPENDENCIES_MISSING " (Debian: libsuitesparse-dev)")
elseif(NOT TARGET sba::SuiteSparse)
  add_library(sba::SuiteSparse INTERFACE IMPORTED)
  set_target_properties(sba::SuiteSparse PROPERTIES
    INTERFACE_LINK_LIBRARIES "${SBA_SUITESPARSE_LIBRARIES}"
    INTERFACE_INCLUDE_DIRECTORIES "${SUITESPARSE_INCLUDE_DIR}")
endif()
string(STRIP "${SBA_DEPENDENCIES_MISSING}" SBA_DEPENDENCIES_MISSING)
