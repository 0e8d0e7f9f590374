//! The arms' link geometry ([`crate::geometry`]) as one `foxglove.SceneUpdate` (Foxglove's own
//! protobuf schema, from its SDK): an entity per body, locked to the body's `/tf` frame
//! (`PSM1/yaw_link`), so a 3D panel draws the arms moving with the transforms, without a URDF.
//! The colours are the camera images': each arm with an RCM its own, the setup joints grey.

use crate::geometry::{tessellate, ArmGeometry};
use crate::Result;
use foxglove::messages::{Color, Point3, SceneEntity, SceneUpdate, TriangleListPrimitive};
use foxglove::{Encode, Schema};

/// The schema and message encoding of [`scene_update`]'s bytes.
pub fn schema() -> (Schema, String) {
    (SceneUpdate::get_schema().expect("the SDK's SceneUpdate has a schema"), SceneUpdate::get_message_encoding())
}

/// Every body of every arm as one entity: arm `a`'s geometry `geometries[a]`, coloured
/// `colors[a]` ([`crate::geometry::arm_color`]), with `body_names[a][body]` as its frame.
pub fn scene_update(geometries: &[ArmGeometry], colors: &[[f32; 3]], body_names: &[Vec<String>]) -> Result<Vec<u8>> {
    let mut entities = Vec::new();
    for ((geometry, &base), names) in geometries.iter().zip(colors).zip(body_names) {
        for (solids, frame) in geometry.bodies.iter().zip(names) {
            let triangles: Vec<TriangleListPrimitive> = solids
                .iter()
                .map(|s| {
                    let c = s.part.color(base);
                    let (v, t) = tessellate(s);
                    TriangleListPrimitive {
                        pose: None,
                        points: v.iter().map(|p| Point3 { x: p.x, y: p.y, z: p.z }).collect(),
                        color: Some(Color { r: c[0] as f64, g: c[1] as f64, b: c[2] as f64, a: 1.0 }),
                        colors: Vec::new(),
                        indices: t.iter().flatten().copied().collect(),
                    }
                })
                .filter(|t| !t.indices.is_empty())
                .collect();
            if triangles.is_empty() {
                continue;
            }
            entities.push(SceneEntity { frame_id: frame.clone(), id: frame.clone(), frame_locked: true, triangles, ..Default::default() });
        }
    }
    let mut buf = Vec::new();
    SceneUpdate { deletions: Vec::new(), entities }.encode(&mut buf).map_err(|e| crate::SimError::Build(format!("scene update: {e}")))?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ARM_COLORS;
    use foxglove::Decode;

    #[test]
    fn every_body_with_geometry_is_an_entity_on_its_tf_frame() {
        let scene = crate::Scene::load("psm").unwrap();
        let sim = crate::Sim::new(&scene, &crate::SimOptions::default()).unwrap();
        let names: Vec<Vec<String>> = sim.arms.iter().map(|a| a.model.bodies.iter().map(|b| format!("{}/{}", a.name, b.name)).collect()).collect();
        let geometry = ArmGeometry::new(&sim.arms[0].model).unwrap();
        let bytes = scene_update(std::slice::from_ref(&geometry), &[ARM_COLORS[0]], &names).unwrap();
        let update = SceneUpdate::decode(bytes.as_slice()).unwrap();
        let drawn = geometry.bodies.iter().filter(|s| !s.is_empty()).count();
        assert_eq!(update.entities.len(), drawn);
        for e in &update.entities {
            assert!(e.frame_locked && names[0].contains(&e.frame_id), "{}", e.frame_id);
            for t in &e.triangles {
                assert!(t.indices.len() % 3 == 0 && t.indices.iter().all(|&i| (i as usize) < t.points.len()));
                // Every vertex within half a metre of its body's frame: the links' own solids.
                assert!(t.points.iter().all(|p| (p.x * p.x + p.y * p.y + p.z * p.z).sqrt() < 0.8), "{}", e.frame_id);
            }
        }
        // The PSM's colour on its links (orange), as in the camera images.
        let c = update.entities[0].triangles[0].color.unwrap();
        assert_eq!([c.r as f32, c.g as f32, c.b as f32], ARM_COLORS[0]);
    }
}
