//! Adam whose moment estimates we hold, so that a checkpoint keeps them and `--resume`
//! continues a training exactly as if it had not stopped.
//!
//! The arithmetic is that of libtorch's C++ `torch::optim::Adam` (the optimiser tch builds,
//! with its defaults: betas 0.9 and 0.999, eps 1e-8, no weight decay), element for element in
//! `f32`, with the scalars rounded where libtorch rounds them, but every operation correctly
//! rounded: libtorch's square root is MKL's, whose last bit follows the processor (its
//! approximate reciprocal square root differs between Intel and AMD), so its weights would
//! too. A test checks the steps against tch's optimiser over many steps (the same but for
//! the last bits).

use std::path::Path;
use tch::Tensor;

/// The first-moment decay of libtorch's (and tch's) default Adam.
const BETA1: f64 = 0.9;
/// The second-moment decay.
const BETA2: f64 = 0.999;
/// The denominator's floor.
const EPS: f64 = 1e-8;

/// The moment estimates of one parameter array.
#[derive(Debug, Clone, PartialEq)]
pub struct Moments {
    /// The running mean of the gradient (libtorch's `exp_avg`).
    pub mean: Vec<f32>,
    /// The running mean of the squared gradient (`exp_avg_sq`).
    pub square: Vec<f32>,
}

impl Moments {
    /// Zero moments of `len` values (before the first step).
    pub fn zeros(len: usize) -> Self {
        Moments {
            mean: vec![0.0; len],
            square: vec![0.0; len],
        }
    }
}

/// Adam over a fixed list of parameter arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct Adam {
    /// Steps taken so far (each parameter's `step` in libtorch).
    pub steps: u64,
    /// One entry per parameter array, in the order `step` receives them.
    pub moments: Vec<Moments>,
}

impl Adam {
    /// A fresh optimiser for parameter arrays of these lengths.
    pub fn new(lengths: &[usize]) -> Self {
        Adam {
            steps: 0,
            moments: lengths.iter().map(|&n| Moments::zeros(n)).collect(),
        }
    }

    /// One step of size `lr`: `params[i]` moves along its gradient `grads[i]` (a descent
    /// step: the gradient is of a loss).
    pub fn step(&mut self, lr: f64, params: &mut [&mut [f32]], grads: &[&[f32]]) {
        assert!(
            params.len() == self.moments.len() && grads.len() == self.moments.len(),
            "one gradient and one moment pair per parameter array"
        );
        self.steps += 1;
        let t = self.steps as f64;
        let correction1 = 1.0 - BETA1.powf(t);
        let correction2 = 1.0 - BETA2.powf(t);
        // libtorch takes each scalar operand as an f32 (the arrays' type).
        let (keep1, take1) = (BETA1 as f32, (1.0 - BETA1) as f32);
        let (keep2, take2) = (BETA2 as f32, (1.0 - BETA2) as f32);
        let (root2, eps) = (correction2.sqrt() as f32, EPS as f32);
        let scale = (-(lr / correction1)) as f32;
        for ((p, g), m) in params.iter_mut().zip(grads).zip(&mut self.moments) {
            assert!(p.len() == g.len() && p.len() == m.mean.len(), "matching lengths");
            for ((&g, mean), square) in g.iter().zip(&mut m.mean).zip(&mut m.square) {
                // exp_avg.mul_(beta1).add_(grad, 1 - beta1): the add is a fused multiply-add.
                *mean = g.mul_add(take1, *mean * keep1);
                // exp_avg_sq.mul_(beta2).addcmul_(grad, grad, 1 - beta2): fused as well.
                *square = (take2 * g).mul_add(g, *square * keep2);
            }
            // denom = exp_avg_sq.sqrt() / sqrt(correction2) + eps, each operation correctly
            // rounded (IEEE 754), as every x86-64 processor computes it. (libtorch's square
            // root is MKL's, whose last bit follows the processor's approximate reciprocal
            // square root: Intel and AMD processors differ there.)
            // param.addcdiv_(exp_avg, denom, -lr / correction1).
            for ((p, &mean), &square) in p.iter_mut().zip(&m.mean).zip(&m.square) {
                let d = square.sqrt() / root2 + eps;
                *p += scale * mean / d;
            }
        }
    }
}

impl Adam {
    /// Member `k` of `members`'s part of the state, as a checkpoint keeps it: its share of
    /// each array (the arrays hold the members one after another, as the stacked parameters
    /// do).
    pub fn member(&self, k: usize, members: usize) -> Adam {
        let part = |v: &[f32]| {
            let n = v.len() / members;
            v[k * n..(k + 1) * n].to_vec()
        };
        Adam {
            steps: self.steps,
            moments: self
                .moments
                .iter()
                .map(|m| Moments {
                    mean: part(&m.mean),
                    square: part(&m.square),
                })
                .collect(),
        }
    }

    /// The state of `members` together (each of the same steps and shapes), as [`Adam::member`]
    /// splits it.
    pub fn of_members(members: &[Adam]) -> Self {
        let join = |i: usize, f: fn(&Moments) -> &Vec<f32>| -> Vec<f32> {
            members
                .iter()
                .flat_map(|m| f(&m.moments[i]).iter().copied())
                .collect()
        };
        Adam {
            steps: members[0].steps,
            moments: (0..members[0].moments.len())
                .map(|i| Moments {
                    mean: join(i, |m| &m.mean),
                    square: join(i, |m| &m.square),
                })
                .collect(),
        }
    }

    /// Writes the state to `path` (safetensors) atomically.
    pub fn save(&self, path: &Path) -> Result<(), tch::TchError> {
        let mut named = vec![("steps".to_string(), Tensor::from_slice(&[self.steps as i64]))];
        for (i, m) in self.moments.iter().enumerate() {
            named.push((format!("{i}.mean"), Tensor::from_slice(&m.mean)));
            named.push((format!("{i}.square"), Tensor::from_slice(&m.square)));
        }
        crate::atomic::write_with(
            path,
            |tmp| Tensor::write_safetensors(&named, tmp),
            tch::TchError::Io,
        )
    }

    /// Reads a state that [`Adam::save`] wrote for arrays of `lengths` values; the
    /// message says what is wrong with a file that does not hold one.
    pub fn load(path: &Path, lengths: &[usize]) -> Result<Self, String> {
        let named: std::collections::HashMap<String, Tensor> = Tensor::read_safetensors(path)
            .map_err(|e| e.to_string())?
            .into_iter()
            .collect();
        let mismatch = || "not Adam's state of this network".to_string();
        let floats = |name: &str, len: usize| -> Result<Vec<f32>, String> {
            let t = named.get(name).filter(|t| t.kind() == tch::Kind::Float);
            let values = t.and_then(|t| Vec::<f32>::try_from(t).ok());
            values.filter(|v| v.len() == len).ok_or_else(mismatch)
        };
        let steps = named
            .get("steps")
            .filter(|t| t.kind() == tch::Kind::Int64 && t.numel() == 1)
            .map(|t| t.int64_value(&[0]))
            .and_then(|s| u64::try_from(s).ok())
            .filter(|_| named.len() == 1 + 2 * lengths.len())
            .ok_or_else(mismatch)?;
        let moments = lengths
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                Ok(Moments {
                    mean: floats(&format!("{i}.mean"), n)?,
                    square: floats(&format!("{i}.square"), n)?,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(Adam { steps, moments })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tch::nn::OptimizerConfig;
    use tch::{Kind, Tensor, nn};

    fn values(t: &Tensor) -> Vec<f32> {
        Vec::try_from(t.flatten(0, -1)).expect("floats")
    }

    #[test]
    fn the_steps_are_libtorchs_adam_but_for_the_last_bits() {
        // Arrays of the lengths of a stack's parameters, odd ones included (libtorch's loops
        // run 8 or 16 lanes and a scalar tail), with gradients of many magnitudes, a learning
        // rate that changes every step, and tch's Adam on the same values as the reference.
        // Each value stays within 1e-6 of libtorch's (a few units in the last place of the
        // values, which start within 0.5 of 0) over 200 steps.
        let lengths = [1usize, 5, 13, 64, 320, 1003];
        let vs = nn::VarStore::new(tch::Device::Cpu);
        let init: Vec<Tensor> = lengths
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                Tensor::from_slice(
                    &(0..n)
                        .map(|k| ((k * 7 + i) % 11) as f32 * 0.1 - 0.5)
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        let vars: Vec<Tensor> = init
            .iter()
            .enumerate()
            .map(|(i, t)| vs.root().var_copy(&format!("p{i}"), t))
            .collect();
        let mut reference = nn::Adam::default().build(&vs, 1e-3).expect("an optimiser");
        let mut ours: Vec<Vec<f32>> = init.iter().map(values).collect();
        let mut adam = Adam::new(&lengths);
        for step in 0..200 {
            let lr = 1e-3 * (0.9f64).powi(step);
            reference.set_lr(lr);
            let grads: Vec<Vec<f32>> = lengths
                .iter()
                .enumerate()
                .map(|(i, &n)| {
                    (0..n)
                        .map(|k| {
                            let x = ((k * 31 + i * 17 + step as usize * 13) % 97) as f32 - 48.0;
                            x * 10f32.powi((k % 9) as i32 - 4)
                        })
                        .collect()
                })
                .collect();
            reference.zero_grad();
            let loss = vars
                .iter()
                .zip(&grads)
                .map(|(v, g)| (v * Tensor::from_slice(g)).sum(Kind::Float))
                .reduce(|a, b| a + b)
                .expect("parameters");
            loss.backward();
            reference.step();
            let mut params: Vec<&mut [f32]> = ours.iter_mut().map(Vec::as_mut_slice).collect();
            let grads: Vec<&[f32]> = grads.iter().map(Vec::as_slice).collect();
            adam.step(lr, &mut params, &grads);
            for (i, (v, o)) in vars.iter().zip(&ours).enumerate() {
                for (a, b) in values(v).iter().zip(o) {
                    assert!((a - b).abs() <= 1e-6, "step {step}, array {i}: {b} vs {a}");
                }
            }
        }
        // The first step by hand: the moments' bias corrections cancel, and each value moves
        // by lr g / (|g| + eps): 1e-3 against the gradient's sign for |g| far above eps, and
        // 1e-3 / 2 for |g| = eps.
        let mut adam = Adam::new(&[3]);
        let mut p = vec![1.0f32, 1.0, 1.0];
        adam.step(1e-3, &mut [&mut p], &[&[2.0, -5e3, 1e-8]]);
        assert_eq!(p, [1.0 - 1e-3, 1.0 + 1e-3, 1.0 - 5e-4]);
    }

    #[test]
    fn a_members_state_round_trips_through_its_file_and_the_stack() {
        // Two members of arrays of 2 and 3 values each: member 1 holds the second half.
        let adam = Adam {
            steps: 7,
            moments: vec![
                Moments {
                    mean: vec![1.0, 2.0, 3.0, 4.0],
                    square: vec![5.0, 6.0, 7.0, 8.0],
                },
                Moments {
                    mean: (0..6).map(|x| x as f32).collect(),
                    square: vec![0.5; 6],
                },
            ],
        };
        let second = adam.member(1, 2);
        assert_eq!(second.moments[0].mean, vec![3.0, 4.0]);
        assert_eq!(second.moments[1].mean, vec![3.0, 4.0, 5.0]);
        assert_eq!(Adam::of_members(&[adam.member(0, 2), second.clone()]), adam);
        let dir = crate::atomic::test_dir("adam");
        let path = dir.join("m.safetensors");
        second.save(&path).unwrap();
        assert_eq!(Adam::load(&path, &[2, 3]), Ok(second));
        let other = Adam::load(&path, &[2, 4]).unwrap_err();
        assert!(other.contains("not Adam's state"), "{other}");
        std::fs::write(&path, b"not safetensors").unwrap();
        assert!(Adam::load(&path, &[2, 3]).is_err(), "a corrupted file");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
