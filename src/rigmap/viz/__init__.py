"""Pictures a person looks at: skeletons, meshes, contact sheets."""
