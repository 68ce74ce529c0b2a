/* SPDX-License-Identifier: BSD-3-Clause */
// The soak's model files (tests/soak/soak.cpp): a generated scene as a COLMAP model with
// quaternions of any size and names that are not UTF-8, and a run's outputs written over it as
// the programs write them (one set, lib/formats/output_file.h): the model, over the input or
// into a directory the run makes, with a PLY file and a report beside it. The disk may fill at
// any byte (a file size limit stands for it), a report may go to a full disk (/dev/full) or
// find its name taken by a directory when the files are renamed. The model is then read back
// and solved by visibility pairs as sbarefine solves it. What the programs promise:
//   a failed run  leaves the case's directory as it was, byte for byte: the input model, no
//                 new file, no new directory, no temporary; but for a report that replaced an
//                 old one before a rename failed after it (output_file.h says why)
//   a run         leaves the model where it was written, its directory holding one model, the
//                 input as it was when written elsewhere, the reports, no temporary
//   the model     read back is the one of the last write that succeeded (names byte for byte)
//   the rotations every quaternion normalizes to a unit one
//   the solve     ends with a finite error no larger than the initial one
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
  bool new_directory = false;   // the second model goes into a directory it makes
  bool old_report = false;      // the report is there from an earlier run
  int failing = 0;  // 0: no report fails; 1: the PLY file goes to /dev/full; 2: its name is taken
};

// Plain data: it crosses a pipe from the soak's child.
struct Outcome {
  int write_failed = 0;  // the run's outputs were not published (as a file size limit may make it)
  int intact = 0;        // the directory is as a failed run or a run must leave it (above)
  int read_back = 0;     // and the model reads back to the one last written
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
