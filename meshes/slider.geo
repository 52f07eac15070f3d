// A slider block 0.1 x 0.06 x 0.06 behind the plane x = 0.
// Physical groups: volume "slider"; surface "pin" (x = 0, centroid at the origin).
SetFactory("OpenCASCADE");
Box(1) = {-0.1, -0.03, -0.03, 0.1, 0.06, 0.06};
eps = 1e-6;
Physical Volume("slider") = {1};
Physical Surface("pin") = Surface In BoundingBox{-eps, -0.1, -0.1, eps, 0.1, 0.1};
