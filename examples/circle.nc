%
O0300 (fdid-fmi example: the 20 mm circle of examples/virtual_circle.csv)
N10 G21 G90 G17 G94
N20 G0 X0 Y-20
N30 G3 X0 Y-20 I0 J20 F6000
N40 M30
%
