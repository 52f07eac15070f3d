// A compact 2 x 1 x 1 block for the finite-difference gradient checks (unstructured Tet4).
// Physical groups: volume "block"; surfaces "clamp" (x = 0) and "tip" (x = 2).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 2, 1, 1};
eps = 1e-6;
Physical Volume("block") = {1};
Physical Surface("clamp") = Surface In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, 1 + eps};
Physical Surface("tip") = Surface In BoundingBox{2 - eps, -eps, -eps, 2 + eps, 1 + eps, 1 + eps};
