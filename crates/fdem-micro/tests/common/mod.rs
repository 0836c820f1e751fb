//! A small real scene for end-to-end checks: spheres on a slightly open lattice, randomly
//! oriented (so that mesh nodes do not line up across a contact), squeezed by six plane
//! walls that move inwards.

/// Scene text: `grid` particles of diameter 15 mm (level-2 linear meshes) on a lattice
/// of pitch `pitch` x 15 mm, walls 10 um outside the outer particles moving inwards at
/// `wall_speed` (m/s), with normal penalty `penalty` (N/m^3), run for `duration` (s) with
/// `outputs` snapshots after t = 0.
pub fn pressed_packing(
    grid: [usize; 3],
    pitch: f64,
    wall_speed: f64,
    penalty: f64,
    duration: f64,
    outputs: usize,
) -> String {
    let d = 0.015;
    let pitch = pitch * d;
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut text = format!(
        "[simulation]\nduration = {duration:e}\noutput_interval = {:e}\n\n\
         [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\n\
         [contact]\nnormal_penalty = {penalty:e}\n\n",
        duration / outputs as f64
    );
    for i in 0..grid[0] {
        for j in 0..grid[1] {
            for k in 0..grid[2] {
                // A random unit quaternion (Shoemake) and a jitter of +-5 um.
                let (u1, u2, u3) = (uniform(), uniform(), uniform());
                let tau = std::f64::consts::TAU;
                let q = [
                    (1.0 - u1).sqrt() * (tau * u2).sin(),
                    (1.0 - u1).sqrt() * (tau * u2).cos(),
                    u1.sqrt() * (tau * u3).sin(),
                    u1.sqrt() * (tau * u3).cos(),
                ];
                let c = [i, j, k].map(|n| n as f64 * pitch + 1e-5 * (uniform() - 0.5));
                text.push_str(&format!(
                    "[[particle]]\ndiameter = {d}\ncenter = [{:e}, {:e}, {:e}]\n\
                     orientation = [{:.17}, {:.17}, {:.17}, {:.17}]\n\
                     mesh = {{ level = 2, order = \"linear\" }}\n\n",
                    c[0], c[1], c[2], q[0], q[1], q[2], q[3]
                ));
            }
        }
    }
    for axis in 0..3 {
        let low = -0.5 * d - 1e-5;
        let high = (grid[axis] - 1) as f64 * pitch + 0.5 * d + 1e-5;
        for (position, sign) in [(low, 1.0), (high, -1.0)] {
            let mut point = [0.0; 3];
            let mut normal = [0.0; 3];
            point[axis] = position;
            normal[axis] = sign;
            let velocity = normal.map(|n| n * wall_speed);
            text.push_str(&format!(
                "[[wall]]\ntype = \"plane\"\npoint = [{:e}, {:e}, {:e}]\n\
                 normal = [{}, {}, {}]\nvelocity = [{}, {}, {}]\n\n",
                point[0],
                point[1],
                point[2],
                normal[0],
                normal[1],
                normal[2],
                velocity[0],
                velocity[1],
                velocity[2]
            ));
        }
    }
    text
}
