#!/bin/bash
# Renders every scene named in a list (default scene_list.txt) with pbrt-v3 (2 threads), appends the wall time of
# each render to renders/times.txt and writes the mean / standard error of each image to renders/results_<list>.
cd "$(dirname "$0")"
LIST=${1:-scene_list.txt}
for s in $(cat $LIST); do
  /usr/bin/time -f "$s %e s" -a -o renders/times.txt ./build/pbrt --nthreads 2 --quiet --outfile renders/$s.pfm scenes/$s.pbrt
done
python3 read_pfm.py $(sed 's|^|renders/|; s|$|.pfm|' $LIST) > renders/results_$LIST
