/* SPDX-License-Identifier: BSD-3-Clause */
// --initial-ply and --final-ply of sbarefine, balsba and eucsbademo: the options that name the
// PLY files (formats/ply.h) and the writing of one when it is asked for.
#ifndef SBA_DEMO_PLY_OPTIONS_H
#define SBA_DEMO_PLY_OPTIONS_H

#include <string>
#include <vector>

#include "cli/cli.h"
#include "formats/ply.h"

namespace sbacli {

// --initial-ply FILE and --final-ply FILE, into *initial and *final_ply; colored: the model's
// points have colors, which the help then mentions.
void add_ply_options(std::vector<Option> *table, std::string *initial, std::string *final_ply, bool colored);

// write_ply for an option, into the run's outputs: nothing when path is empty; "PATH: why" on
// stderr when it fails.
bool write_ply_option(const std::string &path, const sbaformats::Cloud &cloud,
                      sbaformats::OutputSet *outputs);

}  // namespace sbacli

#endif  // SBA_DEMO_PLY_OPTIONS_H
