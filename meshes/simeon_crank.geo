// The crank of Simeon's flexible slider-crank (the IVP test set "crank" problem): 0.15 m along
// x, 10 x 10 mm section (rigid and driven: its inertia does not enter the motion).
// Physical groups: volume "crank"; surfaces "end_a" (x = 0) and "end_b" (x = L).
SetFactory("OpenCASCADE");
L = 0.15; b = 0.01;
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("crank") = {1};
Physical Surface("end_a") = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
Physical Surface("end_b") = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
