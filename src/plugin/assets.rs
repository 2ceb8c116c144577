//! Asset loaders: point clouds (`.ply .xyz .pwn .off .obj`) and scene files (`.ron`).
//!
//! A scene asset loads its cloud as a dependency, found relative to the scene file, so
//! `asset_server.load("scenes/hat.ron")` brings the whole scene. A bad file fails its load
//! with the reader's typed error; the surface that asked for it shows the message in its
//! [`SurfaceStatus`](super::SurfaceStatus).

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::prelude::*;

use crate::core::PointCloud;
use crate::core::cloud::io::{CloudFormat, LoadError, read_cloud_from_bytes};
use crate::core::scene::{MAX_SCENE_BYTES, Scene, SceneError};

/// A point cloud loaded by the asset server.
#[derive(Asset, TypePath, Debug, Clone, Deref)]
pub struct CloudAsset(pub PointCloud);

/// A scene loaded by the asset server, with its cloud.
#[derive(Asset, TypePath, Debug, Clone)]
pub struct SceneAsset {
    /// The scene's settings, pins and pulls.
    pub scene: Scene,
    /// Its dense cloud (a dependency, loaded with it).
    pub cloud: Handle<CloudAsset>,
}

/// Why a cloud or scene asset could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// Reading the file failed.
    #[error("could not read {path}: {source}")]
    Io {
        /// The asset path.
        path: String,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The extension names no cloud format.
    #[error("{0}: unknown point-cloud format")]
    UnknownFormat(String),
    /// The cloud file is malformed.
    #[error(transparent)]
    Cloud(#[from] LoadError),
    /// The scene file is malformed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene names its cloud with a path that is not a valid asset path.
    #[error("{scene}: the cloud path {cloud:?} is not a valid asset path: {message}")]
    CloudPath {
        /// The scene.
        scene: String,
        /// The path given.
        cloud: String,
        /// Why it is not valid.
        message: String,
    },
}

async fn read_all(
    reader: &mut dyn Reader,
    path: &str,
    limit: Option<u64>,
) -> Result<Vec<u8>, AssetError> {
    let io = |source| AssetError::Io {
        path: path.to_owned(),
        source,
    };
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).await.map_err(io)?;
    if let Some(limit) = limit.filter(|&l| bytes.len() as u64 > l) {
        return Err(io(std::io::Error::other(format!(
            "{} bytes is too large (at most {limit})",
            bytes.len()
        ))));
    }
    Ok(bytes)
}

/// Loads point clouds: `.ply` (ASCII or binary), `.xyz`, `.pwn`, `.off`, `.obj`.
#[derive(Debug, Default, TypePath)]
pub struct CloudLoader;

impl AssetLoader for CloudLoader {
    type Asset = CloudAsset;
    type Settings = ();
    type Error = AssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<CloudAsset, AssetError> {
        let path = load_context.path().to_string();
        let format = CloudFormat::from_path(load_context.path().path())
            .ok_or_else(|| AssetError::UnknownFormat(path.clone()))?;
        let bytes = read_all(reader, &path, None).await?;
        Ok(CloudAsset(read_cloud_from_bytes(&bytes, format, &path)?))
    }

    fn extensions(&self) -> &[&str] {
        &["ply", "xyz", "pwn", "off", "obj"]
    }
}

/// Loads scene files (`.ron`, see [`crate::core::scene`]) and their clouds.
#[derive(Debug, Default, TypePath)]
pub struct SceneLoader;

impl AssetLoader for SceneLoader {
    type Asset = SceneAsset;
    type Settings = ();
    type Error = AssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<SceneAsset, AssetError> {
        let path = load_context.path().to_string();
        let bytes = read_all(reader, &path, Some(MAX_SCENE_BYTES)).await?;
        let text = String::from_utf8_lossy(&bytes);
        let scene = Scene::parse(&text, path.as_ref())?;
        let relative = scene.cloud.to_string_lossy().replace('\\', "/");
        let cloud_path = load_context
            .path()
            .resolve_embed_str(&relative)
            .map_err(|e| AssetError::CloudPath {
                scene: path.clone(),
                cloud: relative.clone(),
                message: e.to_string(),
            })?;
        let cloud = load_context.load(cloud_path);
        Ok(SceneAsset { scene, cloud })
    }

    fn extensions(&self) -> &[&str] {
        &["ron"]
    }
}
