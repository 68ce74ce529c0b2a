function sbatest_assert(cond, varargin)
% SBATEST_ASSERT  Fails the running test with the message sprintf(varargin{:}) unless cond.
  if ~cond
    error('sbatest:failed', varargin{:});
  end
end
% SPDX-License-Identifier: BSD-3-Clause
