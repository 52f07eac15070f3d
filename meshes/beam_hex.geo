// The beam of meshes/beam.geo (L = 1, h = 0.05, b = 0.1) as a structured Hex8 mesh:
// a transfinite, recombined x-y rectangle extruded in z with layers.
// Physical groups: volume "beam"; surfaces "clamp" (x = 0) and "tip" (x = L).
L = 1.0; h = 0.05; b = 0.1;
nx = 40; ny = 4; nz = 6;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, h, 0}; Point(4) = {0, h, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3} = nx + 1;
Transfinite Curve{2, 4} = ny + 1;
Transfinite Surface{1};
Recombine Surface{1};
out[] = Extrude {0, 0, b} { Surface{1}; Layers{nz}; Recombine; };
// out[0]: top face (z = b), out[1]: volume, out[2..5]: sides from lines 1..4.
Physical Volume("beam") = {out[1]};
Physical Surface("tip") = {out[3]};
Physical Surface("clamp") = {out[5]};
