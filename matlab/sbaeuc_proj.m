function x = sbaeuc_proj(j, i, aj, bi, qr0, cal)
% SBAEUC_PROJ  Projection of the Euclidean camera of eucsbademo (fixed intrinsics).
%
%   x = sbaeuc_proj(j, i, aj, bi, qr0, cal)
%
% The proj callback of sba for every reftype ('motstr', 'mot' and 'str'): the gateway
% passes both the camera and the point parameters in each mode.
%
%   j, i  zero-based camera and point indices (i is not used)
%   aj    camera j: (v1 v2 v3 t1 t2 t3), the vector part of a small rotation
%         qs = (sqrt(1 - |v|^2), v) applied after the camera's initial rotation, and the
%         translation t (world to camera: Xc = R(qs) R(q0_j) X + t)
%   bi    point i: (X Y Z)
%   qr0   the initial rotations: 4*m values (a 4 x m matrix or a vector), unit quaternions
%         (w x y z) with w >= 0, camera after camera
%   cal   the intrinsics (fu u0 v0 ar s): K = [fu s u0; 0 fu*ar v0; 0 0 1]
%   x     the predicted pixel (u v), a 1 x 2 vector
%
% Outside the unit ball (|v| >= 1, reached at most by a rejected trial step) qs is the
% boundary rotation (0, v/|v|), so that the prediction stays real and finite.
%
% The same model in C is sbaeuc_proj.c, whose rotation eucsbademo's camera model shares
% (lib/cameras/euclidean_rotation.h in the source tree).
%
% See also SBAEUC_PROJAC, SBAEUC_PROJAC_MOT, SBAEUC_PROJAC_STR, EUCSBADEMO, SBA.

  q = qr0(4*j+1:4*j+4);
  v1 = aj(1); v2 = aj(2); v3 = aj(3);
  vv = v1*v1 + v2*v2 + v3*v3;
  if vv < 1
    w = sqrt(1 - vv);
  else
    w = 0; s = sqrt(vv); v1 = v1/s; v2 = v2/s; v3 = v3/s;
  end
  % The rotation of the camera is qs * q0 (Hamilton product; applies q0 first).
  qw = w*q(1) - v1*q(2) - v2*q(3) - v3*q(4);
  qx = w*q(2) + v1*q(1) + v2*q(4) - v3*q(3);
  qy = w*q(3) - v1*q(4) + v2*q(1) + v3*q(2);
  qz = w*q(4) + v1*q(3) - v2*q(2) + v3*q(1);
  X = bi(1); Y = bi(2); Z = bi(3);
  xc = (qw*qw + qx*qx - qy*qy - qz*qz)*X + 2*(qx*qy - qw*qz)*Y + 2*(qx*qz + qw*qy)*Z + aj(4);
  yc = 2*(qx*qy + qw*qz)*X + (qw*qw - qx*qx + qy*qy - qz*qz)*Y + 2*(qy*qz - qw*qx)*Z + aj(5);
  zc = 2*(qx*qz - qw*qy)*X + 2*(qy*qz + qw*qx)*Y + (qw*qw - qx*qx - qy*qy + qz*qz)*Z + aj(6);
  xn = xc / zc;
  yn = yc / zc;
  x = [cal(1)*xn + cal(5)*yn + cal(2), cal(1)*cal(4)*yn + cal(3)];
end
% SPDX-License-Identifier: BSD-3-Clause
