%
O0400 (fdid-fmi example: an obround slot, every junction tangent; try --corner-angle 1)
N10 G21 G90 G17 G94
N20 G0 X0 Y0
N30 G1 X30 F4800
N40 G3 X30 Y16 I0 J8
N50 G1 X0
N60 G3 X0 Y0 I0 J-8
N70 M30
%
