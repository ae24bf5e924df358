%
O0100 (fdid-fmi example: a pocket corner with lines and arcs in XY, metric, G94)
N10 G21 G90 G17 G94
N20 G0 X0 Y0 S8000 M3
N30 G1 X20 F3000
N40 G3 X40 Y0 R10
N50 G1 Y20 F2400
N60 G2 X20 Y20 I-10 J0
N70 G1 X0 Y0 F6000 (back to the start, 45 deg)
N80 M5
N90 M30
%
