// A payload carried on a pin: a cylinder of radius 6 mm and length 10 mm along z, centred at the
// origin, that fills the pin hole of meshes/topopt_rod.geo (its mass comes from the material).
// Physical groups: volume "payload"; surface "mount" (the lateral surface, centroid at the
// origin).
SetFactory("OpenCASCADE");
r = 0.006; T = 0.01;
Cylinder(1) = {0, 0, -T / 2, 0, 0, T, r};
Physical Volume("payload") = {1};
Physical Surface("mount") = {1}; // OpenCASCADE's cylinder: 1 is the lateral surface, 2 and 3 the caps
