"""zencosim: distributed, real-time co-simulation of mechanical and multiphysics systems over Zenoh."""
