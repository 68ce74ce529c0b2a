function err = sbatest_reference(refine, jacobian)
% SBATEST_REFERENCE  The final mean squared error that the C eucsbademo reaches on the
% 7-camera problem with the simple driver: refine 'motstr', 'mot' or 'str'; jacobian
% 'analytic' (default) or 'numeric'. Runs the eucsbademo of the build (SBA_EUCSBADEMO);
% without it, the values it printed when these tests were written (0.675396 is also sba
% 1.6's published figure).
  if nargin < 2
    jacobian = 'analytic';
  end
  fallback = struct('motstr', 0.675396, 'mot', 3.55953, 'str', 5.81031);
  exe = getenv('SBA_EUCSBADEMO');
  if isempty(exe) || exist(exe, 'file') ~= 2
    err = fallback.(refine);
    printf('reference (%s): %g, recorded (no eucsbademo in this build)\n', refine, err);
    return;
  end
  [cams, pts, calib] = sbatest_files();
  args = sprintf('--simple --refine=%s', refine);
  if strcmp(jacobian, 'numeric')
    args = [args ' --numeric-jacobian'];
  end
  cmd = sprintf('"%s" %s "%s" "%s" "%s" 2>&1', exe, args, cams, pts, calib);
  [status, out] = system(cmd);
  tok = regexp(out, 'error ([0-9.eE+-]+) \[initial', 'tokens', 'once');
  sbatest_assert(status == 0 && ~isempty(tok), 'eucsbademo failed (%d): %s\n%s', status, cmd, out);
  err = str2double(tok{1});
  printf('reference (%s, %s Jacobian): C eucsbademo reaches %g\n', refine, jacobian, err);
end
% SPDX-License-Identifier: BSD-3-Clause
