% osv_reference.m - run MSS's unmodified osv.m open loop on an INPUTS.csv, write a STATES.csv.
%
% Usage (GNU Octave, from anywhere):
%   octave-cli -q tools/osv_reference.m MSS_OSV_DIR INPUTS.csv STATES.csv [H]
%
% INPUTS.csv columns (header row, any order): t (s), current_speed (m/s), current_dir_deg (the
% direction the current flows towards, from north), n_1 .. n_4 (rpm; 1, 2 the bow tunnels, 3, 4 the
% stern azimuths) and alpha_3, alpha_4 (deg). Inputs are held from one row to the next, as dpgw's
% `dpgw sim --inputs` does. The state is integrated with MSS's own fixed-step rk4.m (as SIMosv.m does)
% at step H (default 0.05 s, SIMosv.m's sampling time), from rest at the origin with heading 0.
% STATES.csv gets t, north, east, psi_deg, u, v, r_degps at every input row (before that row's inputs
% act). This file is dpgw's; osv.m and its helpers are called unmodified from MSS_OSV_DIR.

args = argv();
if numel(args) < 3
  error('usage: osv_reference.m MSS_OSV_DIR INPUTS.csv STATES.csv [H]');
end
addpath(args{1});
h = 0.05;
if numel(args) >= 4
  h = str2double(args{4});
end

fid = fopen(args{2}, 'r');
header = strtrim(strsplit(fgetl(fid), ','));
fclose(fid);
data = dlmread(args{2}, ',', 1, 0);
col = @(name) data(:, find(strcmp(header, name), 1));

t = col('t');
Vc = col('current_speed');
betaVc = deg2rad(col('current_dir_deg'));
n = [col('n_1') col('n_2') col('n_3') col('n_4')];
alpha = deg2rad([col('alpha_3') col('alpha_4')]);

clear osv;                      % fresh persistent vessel data
x = zeros(12, 1);               % [u v w p q r x y z phi theta psi]
out = zeros(numel(t), 7);
for i = 1:numel(t)
  out(i, :) = [t(i) x(7) x(8) rad2deg(ssa(x(12))) x(1) x(2) rad2deg(x(6))];
  if i < numel(t)
    steps = round((t(i + 1) - t(i)) / h);
    ui = [n(i, :) alpha(i, :)]';
    for k = 1:steps
      x = rk4(@osv, h, x, ui, Vc(i), betaVc(i));
    end
  end
end

fid = fopen(args{3}, 'w');
fprintf(fid, 't,north,east,psi_deg,u,v,r_degps\n');
fprintf(fid, '%.3f,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n', out');
fclose(fid);
