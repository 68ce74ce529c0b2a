// SPDX-License-Identifier: BSD-3-Clause
// The sba_crsm helpers on the sba paper's example: a 4 x 3 index with val 0..7,
// colidx (0,1,1,2,1,2,1,2), rowptr (0,2,4,6,8).
#include <gtest/gtest.h>

#include <vector>

#include "sba.h"

namespace {

struct PaperIndex : ::testing::Test {
  void SetUp() override {
    sba_crsm_alloc(&sm, 4, 3, 8);
    ASSERT_NE(sm.val, nullptr);
    const int colidx[8] = {0, 1, 1, 2, 1, 2, 1, 2}, rowptr[5] = {0, 2, 4, 6, 8};
    for (int k = 0; k < 8; ++k) sm.val[k] = k, sm.colidx[k] = colidx[k];
    for (int r = 0; r < 5; ++r) sm.rowptr[r] = rowptr[r];
  }
  void TearDown() override { sba_crsm_free(&sm); }
  sba_crsm sm{};
};

TEST_F(PaperIndex, AllocSetsSizes) {
  EXPECT_EQ(sm.nr, 4);
  EXPECT_EQ(sm.nc, 3);
  EXPECT_EQ(sm.nnz, 8);
}

TEST_F(PaperIndex, ElementLookups) {
  const int expect[4][3] = {{0, 1, -1}, {-1, 2, 3}, {-1, 4, 5}, {-1, 6, 7}};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(sba_crsm_elmidx(&sm, i, j), expect[i][j]) << i << "," << j;
  EXPECT_EQ(sba_crsm_elmidx(&sm, 4, 0), -1);
  EXPECT_EQ(sba_crsm_elmidx(&sm, -1, 0), -1);
  EXPECT_EQ(sba_crsm_elmidx(&sm, 0, 3), -1);
}

TEST_F(PaperIndex, ElementLookupsWithHint) {
  EXPECT_EQ(sba_crsm_elmidxp(&sm, 1, 2, 1, 2), 3);  // (1,1) at 2, look right
  EXPECT_EQ(sba_crsm_elmidxp(&sm, 1, 1, 2, 3), 2);  // (1,2) at 3, look left
  EXPECT_EQ(sba_crsm_elmidxp(&sm, 1, 0, 1, 2), -1);
  EXPECT_EQ(sba_crsm_elmidxp(&sm, 0, 0, 0, 0), 0);
  EXPECT_EQ(sba_crsm_elmidxp(&sm, 3, 2, 1, 99), 7);  // a wrong hint is ignored
}

TEST_F(PaperIndex, RowListing) {
  int v[3], c[3];
  ASSERT_EQ(sba_crsm_row_elmidxs(&sm, 0, v, c), 2);
  EXPECT_EQ(v[0], 0);
  EXPECT_EQ(v[1], 1);
  EXPECT_EQ(c[0], 0);
  EXPECT_EQ(c[1], 1);
  ASSERT_EQ(sba_crsm_row_elmidxs(&sm, 3, v, c), 2);
  EXPECT_EQ(v[0], 6);
  EXPECT_EQ(v[1], 7);
  EXPECT_EQ(c[0], 1);
  EXPECT_EQ(c[1], 2);
  EXPECT_EQ(sba_crsm_row_elmidxs(&sm, 4, v, c), 0);
}

TEST_F(PaperIndex, ColumnListing) {
  int v[4], r[4];
  ASSERT_EQ(sba_crsm_col_elmidxs(&sm, 0, v, r), 1);
  EXPECT_EQ(v[0], 0);
  EXPECT_EQ(r[0], 0);
  ASSERT_EQ(sba_crsm_col_elmidxs(&sm, 1, v, r), 4);
  const int ev[4] = {1, 2, 4, 6};
  for (int q = 0; q < 4; ++q) {
    EXPECT_EQ(v[q], ev[q]);
    EXPECT_EQ(r[q], q);
  }
  ASSERT_EQ(sba_crsm_col_elmidxs(&sm, 2, v, r), 3);
  EXPECT_EQ(v[0], 3);
  EXPECT_EQ(v[2], 7);
  EXPECT_EQ(r[0], 1);
  EXPECT_EQ(r[2], 3);
  EXPECT_EQ(sba_crsm_col_elmidxs(&sm, 3, v, r), 0);
}

TEST(Crsm, FreeResetsAndToleratesNull) {
  sba_crsm sm{};
  sba_crsm_alloc(&sm, 2, 2, 0);
  ASSERT_NE(sm.rowptr, nullptr);
  sba_crsm_free(&sm);
  EXPECT_EQ(sm.rowptr, nullptr);
  EXPECT_EQ(sm.nnz, 0);
  sba_crsm_free(&sm);  // twice is harmless
  sba_crsm_free(nullptr);
  sba_crsm_alloc(&sm, -1, 2, 3);
  EXPECT_EQ(sm.val, nullptr);
  EXPECT_EQ(sba_crsm_elmidx(nullptr, 0, 0), -1);
  EXPECT_EQ(sba_crsm_row_elmidxs(&sm, 0, nullptr, nullptr), 0);
}

}  // namespace
