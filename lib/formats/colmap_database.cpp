// SPDX-License-Identifier: BSD-3-Clause
// The pose_priors table of COLMAP's database (colmap_priors.h), read with SQLite.
#include <sqlite3.h>

#include <cstring>
#include <memory>
#include <set>

#include "formats/colmap_priors.h"

namespace sbaformats::colmap {
namespace {

struct CloseDb {
  void operator()(sqlite3 *db) const { sqlite3_close(db); }
};
struct Finalize {
  void operator()(sqlite3_stmt *s) const { sqlite3_finalize(s); }
};
using Db = std::unique_ptr<sqlite3, CloseDb>;
using Statement = std::unique_ptr<sqlite3_stmt, Finalize>;

bool prepare(sqlite3 *db, const char *sql, Statement *out, const std::string &path, std::string *error) {
  sqlite3_stmt *s = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) {
    sqlite3_finalize(s);
    *error = path + ": " + sqlite3_errmsg(db);
    return false;
  }
  out->reset(s);
  return true;
}

// The columns of table `pose_priors`; empty when there is no such table.
bool columns(sqlite3 *db, const std::string &path, std::set<std::string> *out, std::string *error) {
  Statement s;
  if (!prepare(db, "PRAGMA table_info(pose_priors)", &s, path, error)) return false;
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    const unsigned char *name = sqlite3_column_text(s.get(), 1);
    if (name) out->insert(reinterpret_cast<const char *>(name));
  }
  if (rc != SQLITE_DONE) {
    *error = path + ": " + sqlite3_errmsg(db);
    return false;
  }
  return true;
}

// A blob of n doubles at column c; a NULL one when null_ok (false: absent).
bool doubles(sqlite3_stmt *s, int c, std::size_t n, bool null_ok, const std::string &what, const std::string &where,
             double *out, bool *present, std::string *error) {
  *present = false;
  if (sqlite3_column_type(s, c) == SQLITE_NULL) {
    if (null_ok) return true;
    *error = where + ": its " + what + " is NULL";
    return false;
  }
  const void *blob = sqlite3_column_blob(s, c);
  const std::size_t bytes = static_cast<std::size_t>(sqlite3_column_bytes(s, c));
  if (sqlite3_column_type(s, c) != SQLITE_BLOB || bytes != n * sizeof(double)) {
    *error = where + ": its " + what + " has " + std::to_string(bytes) + " bytes, expected " +
             std::to_string(n * sizeof(double)) + " (" + std::to_string(n) + " doubles)";
    return false;
  }
  std::memcpy(out, blob, bytes);
  *present = true;
  return true;
}

}  // namespace

bool read_pose_priors_database(const std::string &path, std::vector<PosePrior> *out, std::string *error) {
  out->clear();
  sqlite3 *raw = nullptr;
  // Read only, and never created: a path that names no database is an error, not a new file.
  const int rc = sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr);
  Db db(raw);
  if (rc != SQLITE_OK) {
    *error = path + ": cannot open as an SQLite database: " + (raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc));
    return false;
  }
  std::set<std::string> cols;
  if (!columns(db.get(), path, &cols, error)) return false;
  if (cols.empty()) {
    *error = path + ": the database has no pose_priors table (COLMAP's database, from 3.9 on, keeps the pose priors there)";
    return false;
  }
  const bool v4 = cols.count("corr_data_id") && cols.count("corr_sensor_type");
  if (!v4 && !cols.count("image_id")) {
    *error = path + ": its pose_priors table has neither COLMAP 4's columns (corr_data_id, corr_sensor_type) nor 3.x's "
                    "(image_id)";
    return false;
  }
  const bool has_cov = cols.count("position_covariance") > 0;
  if (!cols.count("position") || !cols.count("coordinate_system")) {
    *error = path + ": its pose_priors table has no position or coordinate_system column";
    return false;
  }
  const std::string sql =
      v4 ? std::string("SELECT pose_prior_id, corr_data_id, corr_sensor_type, position, ") +
               (has_cov ? "position_covariance" : "NULL") + ", coordinate_system FROM pose_priors ORDER BY pose_prior_id"
         : std::string("SELECT image_id, image_id, 0, position, ") + (has_cov ? "position_covariance" : "NULL") +
               ", coordinate_system FROM pose_priors ORDER BY image_id";
  Statement s;
  if (!prepare(db.get(), sql.c_str(), &s, path, error)) return false;
  int step;
  while ((step = sqlite3_step(s.get())) == SQLITE_ROW) {
    const long long id = sqlite3_column_int64(s.get(), 0);
    const long long data = sqlite3_column_int64(s.get(), 1);
    const int sensor_type = sqlite3_column_int(s.get(), 2);
    PosePrior p;
    p.where = path + ": " + (v4 ? "pose prior " + std::to_string(id) + " (data " : std::string("pose prior (image ")) +
              std::to_string(data) + ")";
    // A prior of another sensor than a camera (an IMU's) places no image.
    if (sensor_type != 0) continue;
    if (data < 0 || data > 0xffffffffLL) {
      *error = p.where + ": its image id is outside 0..4294967295";
      return false;
    }
    p.image_id = static_cast<std::uint32_t>(data);
    bool present = false;
    if (!doubles(s.get(), 3, 3, false, "position", p.where, p.position.data(), &present, error) ||
        !doubles(s.get(), 4, 9, true, "position_covariance", p.where, p.covariance.data(), &p.has_covariance, error))
      return false;
    // COLMAP writes its Eigen matrix column by column; a covariance is symmetric, and one that
    // is not is refused, so the order does not change what is used.
    const int system = sqlite3_column_int(s.get(), 5);
    if (system < -1 || system > 1) {
      *error = p.where + ": its coordinate_system is " + std::to_string(system) +
               ", expected -1 (UNDEFINED), 0 (WGS84) or 1 (CARTESIAN)";
      return false;
    }
    p.system = static_cast<PriorSystem>(system);
    out->push_back(p);
  }
  if (step != SQLITE_DONE) {
    *error = path + ": " + sqlite3_errmsg(db.get());
    return false;
  }
  return true;
}

}  // namespace sbaformats::colmap
