// 2 x 1 x 1 box, structured Hex8 (transfinite, recombined): 16 x 8 x 8 elements (the lattice of
// ../../../meshes/box_2x1x1_hex.geo at half its resolution).
// Physical groups: volume "design"; surface "clamp" (x = 0); curve "load_edge" (x = 2, z = 0).
SetFactory("OpenCASCADE");
nx = 16; ny = 8; nz = 8; // ny = nz: the curves in the end planes x = 0, 2 take ny + 1 nodes
Box(1) = {0, 0, 0, 2, 1, 1};
eps = 1e-6;
Transfinite Curve{Curve In BoundingBox{-eps, -eps, -eps, 2 + eps, eps, eps}} = nx + 1;
Transfinite Curve{Curve In BoundingBox{-eps, 1 - eps, -eps, 2 + eps, 1 + eps, eps}} = nx + 1;
Transfinite Curve{Curve In BoundingBox{-eps, -eps, 1 - eps, 2 + eps, eps, 1 + eps}} = nx + 1;
Transfinite Curve{Curve In BoundingBox{-eps, 1 - eps, 1 - eps, 2 + eps, 1 + eps, 1 + eps}} = nx + 1;
Transfinite Curve{Curve In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, 1 + eps}} = ny + 1;
Transfinite Curve{Curve In BoundingBox{2 - eps, -eps, -eps, 2 + eps, 1 + eps, 1 + eps}} = ny + 1;
Transfinite Surface{:};
Recombine Surface{:};
Transfinite Volume{1};
Physical Volume("design") = {1};
Physical Surface("clamp") = Surface In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, 1 + eps};
Physical Curve("load_edge") = Curve In BoundingBox{2 - eps, -eps, -eps, 2 + eps, 1 + eps, eps};
