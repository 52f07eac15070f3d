// Unit square cantilever as a slab one element thick (plane stress with Hex8): nx x ny x 1
// elements, x along the span, y up, z through the thickness t = 1 / nx.
// Physical groups: volume "design"; surface "clamp" (x = 0); curves "corner_top" (x = 1, y = 1)
// and "corner_bottom" (x = 1, y = 0), the edges through the thickness where the loads act.
SetFactory("OpenCASCADE");
nx = 60; ny = 60; t = 1 / nx;
Box(1) = {0, 0, 0, 1, 1, t};
e = 1e-6;
For i In {0:1}
  For j In {0:1}
    // along x at y = i, z = j t; along y at x = i, z = j t
    Transfinite Curve{Curve In BoundingBox{-e, i - e, j * t - e, 1 + e, i + e, j * t + e}} = nx + 1;
    Transfinite Curve{Curve In BoundingBox{i - e, -e, j * t - e, i + e, 1 + e, j * t + e}} = ny + 1;
    // through the thickness at (x, y) = (i, j)
    Transfinite Curve{Curve In BoundingBox{i - e, j - e, -e, i + e, j + e, t + e}} = 2;
  EndFor
EndFor
Transfinite Surface{:};
Recombine Surface{:};
Transfinite Volume{1};
Physical Volume("design") = {1};
Physical Surface("clamp") = Surface In BoundingBox{-e, -e, -e, e, 1 + e, t + e};
Physical Curve("corner_top") = Curve In BoundingBox{1 - e, 1 - e, -e, 1 + e, 1 + e, t + e};
Physical Curve("corner_bottom") = Curve In BoundingBox{1 - e, -e, -e, 1 + e, e, t + e};
