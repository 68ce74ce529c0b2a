function r = sbatest_prior_focal(j, aj, e)
% SBATEST_PRIOR_FOCAL  A callback prior (test_priors): camera j's focal length minus e(j),
% j 1-based.
  r = aj(7) - e(j);
end
% SPDX-License-Identifier: BSD-3-Clause
