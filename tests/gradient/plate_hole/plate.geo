// A plate with a hole (unstructured Tet4): 0.2 x 0.1 x 0.01 m, a hole of radius 0.02 m at its
// centre. Physical groups: volume "plate"; surfaces "clamp" (x = 0) and "tip" (x = 0.2).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.2, 0.1, 0.01};
Cylinder(2) = {0.1, 0.05, -0.001, 0, 0, 0.012, 0.02};
BooleanDifference(3) = {Volume{1}; Delete;}{Volume{2}; Delete;};
eps = 1e-6;
Physical Volume("plate") = {3};
Physical Surface("clamp") = Surface In BoundingBox{-eps, -eps, -eps, eps, 0.1 + eps, 0.01 + eps};
Physical Surface("tip") = Surface In BoundingBox{0.2 - eps, -eps, -eps, 0.2 + eps, 0.1 + eps, 0.01 + eps};
