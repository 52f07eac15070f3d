// A slender bar of length L along x with a square b x b cross-section centred on the x-axis
// (the flexible pendulum). Physical groups: volume "bar"; surfaces "pin" (x = 0), "tip"
// (x = L) and "ends" (both end faces: its centroid is the bar's centre of mass).
SetFactory("OpenCASCADE");
L = 1.0; b = 0.02;
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("bar") = {1};
pin[] = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
tip[] = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
Physical Surface("pin") = {pin[]};
Physical Surface("tip") = {tip[]};
Physical Surface("ends") = {pin[], tip[]};
