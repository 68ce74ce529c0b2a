/* SPDX-License-Identifier: BSD-3-Clause */
// Output of the demo programs: result files that appear whole or not at all, a run's files that
// appear together or not at all, and a check that what they printed on standard output got
// there.
//
// A result file is written under a temporary name beside its final one (FILE.tmp.PID, with a
// counter appended if that name is taken) and renamed onto the final name once it has been
// written, synced to the disk and closed without error; the folder is synced after the rename.
// A run that fails or is killed midway therefore never leaves a truncated file under the final
// name, and an existing file there stays as it was until the new one replaces it. The syncs
// extend that to a power loss: without the first, the rename could reach the disk before the
// data and leave an empty or partial file under the final name; without the second, the
// rename itself could be lost after the run has said it succeeded. A stale FILE.tmp.* may
// remain only when the process is killed (or the power lost) midway.
//
// The files of one run (a model, its reports, a COLMAP model's files) form an OutputSet: all
// are written and closed before any is renamed, so that a run that fails leaves no new file, no
// new directory and every existing file (its inputs among them) as it was (see OutputSet).
//
// Paths that are not (or do not lead to) regular files, such as /dev/null, /dev/stdout or a
// FIFO, are written directly: renaming a temporary onto them would replace the device node or
// link instead of writing to it. A symbolic link to a regular file keeps pointing where it
// did: its target is replaced.
#ifndef SBA_LIB_FORMATS_OUTPUT_FILE_H
#define SBA_LIB_FORMATS_OUTPUT_FILE_H

#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

namespace sbaformats {

// The folder a file at path is written in (its temporary made there and renamed onto it): the
// folder of path as named, or, for a symbolic link, of the file it leads to.
std::string folder_of(const std::string &path);

// Why a file cannot be made in the folder of path, for the errno of a failure that is the
// folder's rather than the file's (no permission, a read-only file system); empty for another.
// A writable file in such a folder cannot be replaced either: its replacement is a new file.
std::string folder_refusal(const std::string &path, int err);

class OutputFile {
 public:
  OutputFile() = default;
  OutputFile(const OutputFile &) = delete;
  OutputFile &operator=(const OutputFile &) = delete;
  // Not committed: the temporary goes away, the final name is left alone.
  ~OutputFile() { discard(); }

  // Creates the file to write. On failure returns false with the reason (strerror text, e.g.
  // "cannot open for writing: No such file or directory", or folder_refusal's for a folder that
  // takes no new file) in *why.
  bool open(const std::string &path, std::string *why);

  std::FILE *get() const { return file_; }

  // Closes the file and gives it its final name. On a write, sync, close or rename error returns
  // false with the reason in *why; the temporary is then removed and the final name untouched.
  // A failure to sync the folder after the rename is said as a write error too, and the file
  // the rename put where nothing was is removed again.
  bool commit(std::string *why);

  // commit() in two steps, for files that appear together: close() ends the writing (the data
  // synced to the disk unless the file is written in place; false, the temporary removed, on a
  // write, sync or close error: "write failed: REASON"), publish() renames the closed file onto
  // its final name and syncs its folder (false on a failure of either; after a failed sync of
  // the folder the file is in place, and unpublish() takes it back). A file closed and not
  // published is removed with its OutputFile.
  bool close(std::string *why);
  bool publish(std::string *why);

  // Removes the file publish() put where nothing was: false (nothing done) when it replaced a
  // file, or was written in place, since what was there is gone either way.
  bool unpublish();

  // The temporary's name while one is open (for tests and messages); empty otherwise.
  const std::string &temporary() const { return temp_; }

  // The descriptor under the stream and the errno of its first write or close failure: ferror
  // says only that a write failed, and errno has often moved on by the time anyone asks.
  struct Descriptor {
    int fd = -1;
    int error = 0;
  };

 private:
  bool attach(int fd, std::string *why);
  void discard();

  std::FILE *file_ = nullptr;
  Descriptor io_;          // under file_
  std::string final_;      // where the file ends up
  std::string temp_;       // the temporary, empty when writing in place or when none is open
  bool replaces_ = false;  // something was at final_ when the file was opened
  bool created_ = false;   // publish() made final_, where nothing was
};

// The files of one run, published together: every one is written and closed under its
// temporary first, and commit() renames them all onto their names only once every one is
// written. Until then, and whenever anything fails, the set takes back what it did: it removes
// its temporaries and the directories it made (those left empty), and no existing file has
// changed. A set not committed does the same when it goes.
//
// The renames themselves can fail midway (a rename needs room in the directory, a target may
// have become a directory): what is renamed by then is not all undone, so the order of the
// renames is chosen to keep that window harmless.
// - The files marked publish_last (the model a run writes, which may be its own input: sbarefine
//   MODEL --write MODEL) go after all the others (its reports: --json, the PLY files ...), so a
//   rename that fails among the reports leaves the model, and with it the run's input, as it
//   was. Within each part the files go in the order they were created: a COLMAP model creates
//   its cameras file last, since a reader takes a directory's model by it (colmap_io.cpp).
// - A failed commit removes again the files it had put where nothing was, so that no new file
//   remains; one that replaced an existing file stays replaced (what it replaced is gone).
// - The files to remove (remove_on_commit: the other encoding's model beside a COLMAP model)
//   go after every rename, so that the directory holds a whole model at every moment; a removal
//   that fails is reported with the new files in place.
// Devices and FIFOs are written in place (see OutputFile): what went into them stays there.
class OutputSet {
 public:
  OutputSet() = default;
  OutputSet(const OutputSet &) = delete;
  OutputSet &operator=(const OutputSet &) = delete;
  ~OutputSet() { discard(); }

  // dir as a directory to write into, made when missing (and then removed again, if left
  // empty, unless the set is committed). False with "DIR: why" in *error if it cannot be.
  bool make_directory(const std::string &dir, std::string *error);

  // A new file of the set, open for writing under its temporary: null, with the reason (as
  // OutputFile::open gives it) in *why, when it cannot be created.
  OutputFile *create(const std::string &path, std::string *why);
  // Ends the writing of a file create() returned: false, with the reason in *why and the file
  // no longer part of the set, on a write, sync or close error.
  bool close(OutputFile *file, std::string *why);
  // Takes a file create() returned out of the set, its temporary removed: a writer that gives
  // up on it.
  void drop(OutputFile *file);

  // Calls write(), which creates files in this set (the run's model), and marks the files it
  // created to be renamed after every other file of the set, whatever is created later (see
  // above). Returns what write() returns.
  template <class Write>
  bool publish_last(Write write) {
    const std::size_t first = files_.size();
    if (!write()) return false;
    for (std::size_t k = first; k < files_.size(); ++k) files_[k].last = true;
    return true;
  }

  // A file commit() removes: `what` it is ("PATH: cannot remove WHAT: why" when that fails),
  // and `why` it goes, for the program to say (removed()).
  struct Removal {
    std::string path, what, why;
  };

  // path is removed once every file of the set is in place (a missing one is no error).
  void remove_on_commit(const std::string &path, const std::string &what, const std::string &why) {
    removals_.push_back({path, what, why});
  }
  // The files the last commit removed (those of remove_on_commit that were there), in order.
  const std::vector<Removal> &removed() const { return removed_; }

  // Renames every file onto its name (devices and FIFOs: already written), then removes the
  // files remove_on_commit named. False with "PATH: why" in *error on the first failure; the
  // set then takes back what it can (see above).
  bool commit(std::string *error);

  // Takes back everything: the temporaries, the files a failed commit published where nothing
  // was, the directories made (those that are empty).
  void discard();

 private:
  struct Entry {
    std::unique_ptr<OutputFile> file;  // where the file's temporary is known; not movable
    std::string path;                  // as the caller named it, for messages
    bool last;
  };
  bool failed(const std::string &path, const std::string &why, std::string *error);

  std::vector<Entry> files_;
  std::vector<std::string> made_;  // directories made, in order
  std::vector<Removal> removals_;
  std::vector<Removal> removed_;
};

// The file a writer streams into: in *set (renamed when the set is committed) or, set null, a
// file of its own, renamed when close() succeeds. Reasons as OutputFile gives them.
class SetFile {
 public:
  explicit SetFile(OutputSet *set) : set_(set) {}
  SetFile(const SetFile &) = delete;
  SetFile &operator=(const SetFile &) = delete;
  // A file left unclosed (its writer failed) is not part of the set.
  ~SetFile();
  bool open(const std::string &path, std::string *why);
  std::FILE *get() const { return file_->get(); }
  bool close(std::string *why);

 private:
  OutputSet *set_;
  OutputFile own_;
  OutputFile *file_ = nullptr;
};

// Writes text as the whole file path: into *set, or (set null) renamed onto path at once. False
// with "PATH: why" in *error if it cannot.
bool write_whole_file(const std::string &path, const std::string &text, std::string *error,
                      OutputSet *set = nullptr);

// Checks before a long computation that path can be written, without changing an existing
// file and without leaving a new one behind: false with the reason in *why if not. Devices
// and FIFOs pass unopened: opening a FIFO could block, or end the stream its reader waits on.
// The folder must take a new file (the temporary a file is written under), even when the file
// itself is writable.
bool probe_writable(const std::string &path, std::string *why);

// Flushes standard output and reports whether everything printed on it was written; if not,
// prints "PROGRAM: error writing standard output: REASON" on stderr and returns false. A run
// whose report was lost (a full disk, a closed stdout) must not exit as a success. Call it where
// the output ends (before publish_outputs, and at exit for what follows), without flushing
// stdout before: the flush made here is the one whose errno is known.
bool stdout_written(const char *program);

// The end of a run that wrote files: its outputs are published (OutputSet::commit) once all
// that it printed on standard output got there, so that a run that fails at the last moment
// still leaves its inputs as they were. False when either fails, said on stderr
// ("PATH: why" for a file).
bool publish_outputs(const char *program, OutputSet *outputs);

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_OUTPUT_FILE_H
