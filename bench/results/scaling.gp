# gnuplot script written by bench/run_suite.py; run in bench/results: gnuplot scaling.gp
set terminal pngcairo size 1400,600 font 'sans,10' noenhanced
set output 'scaling.png'
set multiplot layout 1,2 title 'Scaling series (sbagen path, fixed K, tracks 2..10)'
set logscale xy
set grid
set key top left
set xlabel 'observations'
set ylabel 'time per iteration [ms] (sba: outer iteration; Ceres: LM step)'
plot 'scaling.dat' index 0 using 1:($2*1000) with linespoints title 'Ceres DENSE_SCHUR, 2 thr', \
     'scaling.dat' index 1 using 1:($2*1000) with linespoints title 'Ceres SPARSE_SCHUR, 2 thr', \
     'scaling.dat' index 2 using 1:($2*1000) with linespoints title 'sba chol, 2 thr', \
     'scaling.dat' index 3 using 1:($2*1000) with linespoints title 'sba sparse-chol, 2 thr'
set ylabel 'peak RSS [MB]'
plot 'scaling.dat' index 0 using 1:3 with linespoints title 'Ceres DENSE_SCHUR, 2 thr', \
     'scaling.dat' index 1 using 1:3 with linespoints title 'Ceres SPARSE_SCHUR, 2 thr', \
     'scaling.dat' index 2 using 1:3 with linespoints title 'sba chol, 2 thr', \
     'scaling.dat' index 3 using 1:3 with linespoints title 'sba sparse-chol, 2 thr'
unset multiplot
