# gnuplot script written by bench/run_suite.py; run in bench/results: gnuplot orbit_series.gp
set terminal pngcairo size 1400,600 font 'sans,10' noenhanced
set output 'orbit_series.png'
set multiplot layout 1,2 title 'Orbit series (sbagen orbit, fixed K, 100 points per camera, tracks 3..40)'
set logscale xy
set grid
set key top left
set xlabel 'observations'
set ylabel 'time per iteration [ms] (sba: outer iteration; Ceres: LM step)'
plot 'orbit_series.dat' index 0 using 1:($2*1000) with linespoints title 'Ceres ITERATIVE_SCHUR, 2 thr', \
     'orbit_series.dat' index 1 using 1:($2*1000) with linespoints title 'sba chol, 2 thr', \
     'orbit_series.dat' index 2 using 1:($2*1000) with linespoints title 'sba iterative-schur, 2 thr', \
     'orbit_series.dat' index 3 using 1:($2*1000) with linespoints title 'sba sparse-chol, 2 thr'
set ylabel 'peak RSS [MB]'
plot 'orbit_series.dat' index 0 using 1:3 with linespoints title 'Ceres ITERATIVE_SCHUR, 2 thr', \
     'orbit_series.dat' index 1 using 1:3 with linespoints title 'sba chol, 2 thr', \
     'orbit_series.dat' index 2 using 1:3 with linespoints title 'sba iterative-schur, 2 thr', \
     'orbit_series.dat' index 3 using 1:3 with linespoints title 'sba sparse-chol, 2 thr'
unset multiplot
