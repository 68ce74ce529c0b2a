/* SPDX-License-Identifier: BSD-3-Clause */
// The soak's model files (tests/soak/soak.cpp): a generated scene as a COLMAP model with
// quaternions of any size and names that are not UTF-8, written over a model in a directory
// on a disk that may fill at any byte (a file size limit stands for it), read back, and
// solved by visibility pairs as sbarefine solves it. What the programs promise:
//   the write      succeeds, or fails and leaves the directory's files as they were, no
//                  temporary beside them
//   the directory  holds one model, the one of the last write that succeeded, and reads back
//                  to it (names byte for byte)
//   the rotations  every quaternion normalizes to a unit one
//   the solve      ends with a finite error no larger than the initial one
#ifndef SBA_SOAK_MODEL_FILES_H
#define SBA_SOAK_MODEL_FILES_H

#include <string>

namespace soakfiles {

struct Case {
  unsigned seed = 0;
  int cameras = 3, points = 20;
  double q_scale = 1;     // every quaternion multiplied by it (1e300, 1e-200 ...)
  bool odd_names = false;  // image names with bytes that are not UTF-8
  bool binary = false;     // the first model's encoding ...
  bool rewrite_binary = false;  // ... and the second's, written over it
  long file_limit = 0;          // RLIMIT_FSIZE during the second write; 0: none
};

// Plain data: it crosses a pipe from the soak's child.
struct Outcome {
  int write_failed = 0;  // the second write failed (as a file size limit may make it)
  int intact = 0;        // the directory holds the model of the last write that succeeded
  int read_back = 0;     // and it reads back to that model
  int rotations = 0;     // every quaternion normalized to a unit one
  int solved = 0;        // the solve ended finite, no worse than it began
  int done = 0;
};

// Runs the case in a directory of its own under TMPDIR (removed after).
void run(const Case &c, Outcome *out);

// Empty when the outcome is one the programs promise; else what is wrong.
std::string judge(const Outcome &o);

}  // namespace soakfiles

#endif
