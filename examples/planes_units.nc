%
O0200 (fdid-fmi example: arcs in G17/G18/G19, inch blocks, incremental moves, inverse time)
N10 G21 G90 G17 G94 F1800
N20 G1 X10 Y0
N30 G2 X20 Y0 I5 J0
N40 G18 G3 X25 Z-5 R5 (ZX plane)
N50 G19 G2 Y5 Z0 R5 (YZ plane)
N60 G17 G20 G91 G1 X0.2 Y0.2 F60 (inch, incremental)
N70 G21 G90 G93 G1 X10 Y10 F20 (inverse time: 3 s)
N80 G94 G1 X0 Y0 F2400
N90 M30
%
