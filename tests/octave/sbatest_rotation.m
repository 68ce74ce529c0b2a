function R = sbatest_rotation(w)
% SBATEST_ROTATION  The rotation matrix of the axis-angle vector w (Rodrigues' formula).
  th = norm(w);
  if th == 0
    R = eye(3);
    return
  end
  K = [0 -w(3) w(2); w(3) 0 -w(1); -w(2) w(1) 0] / th;
  R = eye(3) + sin(th) * K + (1 - cos(th)) * (K * K);
end
% SPDX-License-Identifier: BSD-3-Clause
