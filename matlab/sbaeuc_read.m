function prob = sbaeuc_read(camsfile, ptsfile, calibfile)
% SBAEUC_READ  Read an eucsbademo problem (fixed intrinsics) for SBA.
%
%   prob = sbaeuc_read(camsfile, ptsfile, calibfile)
%
% Reads the three text files of eucsbademo (formats: docs/formats.md):
%   camsfile   one camera per line: q0 q1 q2 q3 tx ty tz (rotation quaternion, scalar part
%              first, then the translation; world to camera)
%   ptsfile    one point per line: X Y Z nframes, then per frame 'f x y' (f zero-based),
%              optionally followed by the 2x2 covariance of the projection, as four values
%              (cxx cxy cxy cyy) or the upper triangle (cxx cxy cyy), the same form throughout
%   calibfile  the 3x3 intrinsics K, row by row
% Lines starting with '#' are comments. Frames out of order within a track are sorted.
%
% prob is a struct with the arguments of SBA for the Euclidean camera of SBAEUC_PROJ:
%   n, m, cnp (6), pnp (3), mnp (2), vmask (n x m sparse logical), nvis,
%   p0 (row vector: m cameras (0 0 0 t) then n points), x (row vector, point by point,
%   cameras ascending), covx ([] or the nvis 2x2 covariances), qr0 (4 x m initial unit
%   quaternions with w >= 0), cal ((fu u0 v0 ar s) from K), K.
%
% See also EUCSBADEMO, SBAEUC_PROJ, SBA.

  cams = read_rows(camsfile);
  if isempty(cams)
    error('sbaeuc_read:format', '%s: no camera found', camsfile);
  end
  widths = cellfun(@numel, cams(:, 1));
  if any(widths ~= 7)
    k = find(widths ~= 7, 1);
    error('sbaeuc_read:format', ['%s:%d: expected 7 values (q0 q1 q2 q3 tx ty tz) but found %d;' ...
          ' this demo handles fixed intrinsics only'], camsfile, cams{k, 2}, widths(k));
  end
  m = size(cams, 1);
  C = reshape([cams{:, 1}], 7, m);
  qr0 = C(1:4, :);
  qn = sqrt(sum(qr0 .^ 2, 1));
  if any(qn == 0)
    error('sbaeuc_read:format', '%s: camera %d has a zero quaternion', camsfile, find(qn == 0, 1));
  end
  qr0 = qr0 ./ repmat(qn .* sign_nonneg(qr0(1, :)), 4, 1);

  K = read_rows(calibfile);
  if size(K, 1) < 3 || any(cellfun(@numel, K(1:3, 1)) ~= 3)
    error('sbaeuc_read:format', '%s: expected 3 rows of 3 values (the matrix K)', calibfile);
  end
  K = [K{1, 1}; K{2, 1}; K{3, 1}];
  cal = [K(1, 1), K(1, 3), K(2, 3), K(2, 2) / K(1, 1), K(1, 2)];

  rows = read_rows(ptsfile);
  n = size(rows, 1);
  if n == 0
    error('sbaeuc_read:format', '%s: no point found', ptsfile);
  end
  pts = zeros(3, n);
  I = cell(n, 1); J = cell(n, 1); XY = cell(n, 1); CV = cell(n, 1);
  covform = 0;   % values per projection: 3 (none), 6 (upper triangle) or 7 (full)
  for i = 1:n
    r = rows{i, 1};
    where = sprintf('%s:%d', ptsfile, rows{i, 2});
    if numel(r) < 4
      error('sbaeuc_read:format', '%s: expected X Y Z nframes ...', where);
    end
    nf = r(4);
    if nf < 1 || nf ~= fix(nf)
      error('sbaeuc_read:format', '%s: bad frame count %g', where, nf);
    end
    per = (numel(r) - 4) / nf;
    if ~any(per == [3 6 7])
      error('sbaeuc_read:format', '%s: %d values for %d frames', where, numel(r) - 4, nf);
    end
    if covform == 0
      covform = per;
    elseif per ~= covform
      error('sbaeuc_read:format', '%s: covariances not given in the same form as before', where);
    end
    T = reshape(r(5:end), per, nf);
    f = T(1, :);
    if any(f < 0 | f >= m | f ~= fix(f)) || numel(unique(f)) ~= nf
      error('sbaeuc_read:format', '%s: bad or repeated frame index', where);
    end
    [f, order] = sort(f);
    T = T(:, order);
    pts(:, i) = r(1:3)';
    I{i} = repmat(i, 1, nf);
    J{i} = f + 1;
    XY{i} = T(2:3, :);
    if per == 7
      CV{i} = T(4:7, :);
    elseif per == 6
      CV{i} = T([4 5 5 6], :);
    end
  end
  Iall = [I{:}]; Jall = [J{:}];
  prob.n = n; prob.m = m; prob.cnp = 6; prob.pnp = 3; prob.mnp = 2;
  prob.vmask = sparse(Iall, Jall, true, n, m);
  prob.nvis = numel(Iall);
  prob.p0 = [reshape([zeros(3, m); C(5:7, :)], 1, []), reshape(pts, 1, [])];
  prob.x = reshape([XY{:}], 1, []);
  if covform > 3
    prob.covx = reshape([CV{:}], 1, []);
  else
    prob.covx = [];
  end
  prob.qr0 = qr0;
  prob.cal = cal;
  prob.K = K;
end

function s = sign_nonneg(w)
  s = ones(size(w));
  s(w < 0) = -1;
end

% The numeric rows of a text file, skipping blank lines and '#' comments: an r x 2 cell of
% {values (row vector), line number}.
function rows = read_rows(file)
  fid = fopen(file, 'r');
  if fid < 0
    error('sbaeuc_read:open', 'cannot open %s', file);
  end
  text = fread(fid, Inf, '*char')';
  fclose(fid);
  lines = regexp(text, '\r?\n', 'split');
  rows = cell(numel(lines), 2);
  count = 0;
  for k = 1:numel(lines)
    s = strtrim(lines{k});
    if isempty(s) || s(1) == '#'
      continue;
    end
    [v, ~, msg] = sscanf(s, '%f');
    if ~isempty(msg) || any(~isfinite(v))
      error('sbaeuc_read:format', '%s:%d: not a list of finite numbers', file, k);
    end
    count = count + 1;
    rows{count, 1} = v(:)';
    rows{count, 2} = k;
  end
  rows = rows(1:count, :);
end
% SPDX-License-Identifier: BSD-3-Clause
