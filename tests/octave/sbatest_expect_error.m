function sbatest_expect_error(args, id, pattern)
% SBATEST_EXPECT_ERROR  Fails the running test unless sba(args{:}) raises the error ID with
% a message that matches the regular expression PATTERN (SBATEST_CHECK_ERROR).
  try
    sba(args{:});
  catch err
    sbatest_check_error(err, id, pattern);
    return;
  end
  error('sbatest:failed', 'no error; expected %s: %s', id, pattern);
end
% SPDX-License-Identifier: BSD-3-Clause
