// The L-bracket of the stress-constrained topology optimization literature (Le et al. 2010;
// the setup of Giraldo-Londono & Paulino's PolyStress, 2021) as a thin plate: a 100 x 100 mm
// square without its top-right 60 x 60 mm, 5 mm thick, structured Hex8 (h = 1 mm in the plane,
// 2 layers through the thickness). Physical groups: volumes "design" (all but the pad) and
// "pad" (x in [95, 100] mm, y in [34, 40] mm: the solid block that takes the load); surfaces
// "clamp" (the top edge y = 100 mm) and "load" (the pad's face x = 100 mm: the top 15 % of the
// arm's depth).
h = 1.0e-3; t = 5.0e-3; layers = 2;
xs[] = {0, 0.040, 0.095, 0.100};
ys[] = {0, 0.034, 0.040, 0.100};
// Cells (i, j) of the grid xs x ys that belong to the L: column 0 for every row, columns 1 and
// 2 for rows 0 and 1 only.
p = 0;
For j In {0:3}
  For i In {0:3}
    p++; Point(p) = {xs[i], ys[j], 0};
    pt[4 * j + i] = p;
  EndFor
EndFor
nl = 0;
For j In {0:3}   // horizontal lines (i, j) -> (i + 1, j)
  For i In {0:2}
    nl++; Line(nl) = {pt[4 * j + i], pt[4 * j + i + 1]};
    hl[3 * j + i] = nl;
    Transfinite Curve{nl} = Round((xs[i + 1] - xs[i]) / h) + 1;
  EndFor
EndFor
For j In {0:2}   // vertical lines (i, j) -> (i, j + 1)
  For i In {0:3}
    nl++; Line(nl) = {pt[4 * j + i], pt[4 * (j + 1) + i]};
    vl[4 * j + i] = nl;
    Transfinite Curve{nl} = Round((ys[j + 1] - ys[j]) / h) + 1;
  EndFor
EndFor
ns = 0;
For j In {0:2}
  For i In {0:2}
    If (i == 0 || j < 2)
      Curve Loop(100 + 3 * j + i) = {hl[3 * j + i], vl[4 * j + i + 1], -hl[3 * (j + 1) + i], -vl[4 * j + i]};
      Plane Surface(100 + 3 * j + i) = {100 + 3 * j + i};
      Transfinite Surface{100 + 3 * j + i};
      Recombine Surface{100 + 3 * j + i};
    EndIf
  EndFor
EndFor
design_faces[] = {100, 101, 102, 103, 104, 106};
pad_faces[] = {105};
dv[] = {};
For k In {0:#design_faces[] - 1}
  out[] = Extrude {0, 0, t} { Surface{design_faces[k]}; Layers{layers}; Recombine; };
  dv[] += out[1];
EndFor
out[] = Extrude {0, 0, t} { Surface{pad_faces[0]}; Layers{layers}; Recombine; };
pv = out[1];
eps = 1e-6;
Physical Volume("design") = dv[];
Physical Volume("pad") = {pv};
Physical Surface("clamp") = Surface In BoundingBox{-eps, 0.1 - eps, -eps, 0.04 + eps, 0.1 + eps, t + eps};
Physical Surface("load") = Surface In BoundingBox{0.1 - eps, 0.034 - eps, -eps, 0.1 + eps, 0.04 + eps, t + eps};
