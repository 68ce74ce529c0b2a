function sbatest_check_error(err, id, pattern)
% SBATEST_CHECK_ERROR  Fails the running test unless err has the identifier ID and a message
% that matches PATTERN and starts with "sba: "; prints the message.
  sbatest_assert(strcmp(err.identifier, id), 'identifier %s instead of %s (message: %s)', ...
                 err.identifier, id, err.message);
  sbatest_assert(~isempty(regexp(err.message, pattern, 'once')), ...
                 'message "%s" does not match "%s"', err.message, pattern);
  sbatest_assert(strncmp(err.message, 'sba: ', 5), 'message "%s" does not start with "sba: "', err.message);
  printf('ok: %s\n', err.message);
end
% SPDX-License-Identifier: BSD-3-Clause
